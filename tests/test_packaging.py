"""A wheel of the project holds every subpackage under minimaxplan, and imports from it."""

import pathlib
import subprocess
import sys
import zipfile

ROOT = pathlib.Path(__file__).resolve().parents[1]
SUBPACKAGES = ("models", "kernels", "verify", "planners", "scenarios", "analysis")


def test_wheel_contains_and_imports_every_subpackage(tmp_path):
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", str(ROOT), "--no-deps", "--quiet", "-w", str(tmp_path)],
        check=True,
        capture_output=True,
    )
    (wheel,) = tmp_path.glob("minimaxplan-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    assert "minimaxplan/__init__.py" in names
    for sub in SUBPACKAGES:
        assert f"minimaxplan/{sub}/__init__.py" in names
    assert not any(name.startswith(("models/", "tests/", "benchmarks/")) for name in names)
    target = tmp_path / "site"
    zipfile.ZipFile(wheel).extractall(target)
    probe = (
        "import minimaxplan, minimaxplan.models, minimaxplan.planners; "
        "print(minimaxplan.__file__); print(minimaxplan.models.Box([0.0], [1.0]))"
    )
    out = subprocess.run(
        [sys.executable, "-c", probe],
        cwd=tmp_path,
        check=True,
        capture_output=True,
        text=True,
        env={"PYTHONPATH": str(target), "PATH": "/usr/bin:/bin"},
    ).stdout
    assert str(target) in out.splitlines()[0]  # imported from the wheel, not the work tree
    assert "Box(low=[0.0], high=[1.0])" in out
