"""`benchmarks/run_all.py`: a filter picks the scripts, and each script sees only its own name in sys.argv."""

import runpy
import sys


def test_a_filtered_run_hands_each_script_an_empty_command_line(benchmark_script, monkeypatch, capsys):
    run_all = benchmark_script("run_all")
    seen = []
    monkeypatch.setattr(runpy, "run_path", lambda path, run_name: seen.append((path, list(sys.argv))))
    monkeypatch.setattr(sys, "argv", ["run_all.py", "bench_forecast", "bench_driving"])
    assert run_all.main() == 0
    names = [path.rsplit("/", 1)[-1] for path, _ in seen]
    assert names == ["bench_driving.py", "bench_forecast.py"]
    assert all(argv == [path] for path, argv in seen)  # not run_all's filter words, which argparse would refuse


def test_a_filter_that_matches_nothing_fails(benchmark_script, monkeypatch, capsys):
    run_all = benchmark_script("run_all")
    monkeypatch.setattr(sys, "argv", ["run_all.py", "no_such_benchmark"])
    assert run_all.main() == 1
    assert "no benchmark matched" in capsys.readouterr().err
