"""The forecast's commit comparison: it tells equal bits from nearly equal ones, and refuses what is not a commit."""

import numpy as np


def test_same_bits_names_a_one_ulp_change_and_a_signed_zero(benchmark_script, tmp_path):
    compare = benchmark_script("compare_forecast_commits")
    base = {"a": np.array([1.0, np.nan, np.inf]), "b": np.array([0.0, 2.0]), "c": np.array([True, False])}
    np.savez(tmp_path / "one.npz", **base)
    np.savez(tmp_path / "same.npz", **{k: v.copy() for k, v in base.items()})
    np.savez(
        tmp_path / "other.npz",
        a=np.array([np.nextafter(1.0, 2.0), np.nan, np.inf]),
        b=np.array([-0.0, 2.0]),
        c=base["c"],
    )
    assert compare._same_bits(tmp_path / "one.npz", tmp_path / "same.npz") == []
    assert compare._same_bits(tmp_path / "one.npz", tmp_path / "other.npz") == ["a", "b"]


def test_a_name_that_is_not_a_commit_is_refused_with_status_2(benchmark_script, capsys):
    compare = benchmark_script("compare_forecast_commits")
    assert compare.main(["no-such-revision-xyz"]) == 2
    assert "no-such-revision-xyz" in capsys.readouterr().err
    assert compare.main([]) == 2
