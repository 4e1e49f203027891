"""docs/rewards.md's example runs as printed: a user's reward gets a compiled box minimum.

It runs in a fresh process with its own numba cache directory: the kernels it compiles
for the example's params type stay out of the project's caches.
"""

import os
import pathlib
import re
import subprocess
import sys

DOC = pathlib.Path(__file__).resolve().parents[2] / "docs" / "rewards.md"


def test_speed_limit_example_runs_as_printed(tmp_path):
    module, usage = re.findall(r"```python\n(.*?)```", DOC.read_text(), flags=re.S)
    assert module.startswith('"""speed_limit_reward.py')
    (tmp_path / "speed_limit_reward.py").write_text(module)
    (tmp_path / "usage.py").write_text(usage)
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba_cache"), "PYTHONPATH": str(tmp_path)}
    out = subprocess.run(
        [sys.executable, str(tmp_path / "usage.py")],
        cwd=tmp_path,
        env=env,
        check=True,
        capture_output=True,
        text=True,
        timeout=600,
    ).stdout
    assert out.splitlines() == ["0.5 False", "True False"]
