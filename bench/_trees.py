"""Another commit's package beside this one: a bench that runs the same scenes under two
trees, each in its own process.

    from _trees import archive, run_worker
    short = archive("98f7025", Path(tmp))            # mirrorgraph/ at that commit in tmp
    rows = run_worker(Path(tmp), "bench_x.py", ["--worker", "exact"], nice=10)
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tarfile
from pathlib import Path

__all__ = ["archive", "run_worker"]

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent


def archive(rev: str, into: Path) -> str:
    """``mirrorgraph/`` at ``rev`` extracted into ``into``; its short commit."""
    short = subprocess.run(["git", "rev-parse", "--short", rev], cwd=ROOT, check=True,
                           capture_output=True, text=True).stdout.strip()
    tar = into / "src.tar"
    subprocess.run(["git", "archive", "-o", str(tar), rev, "mirrorgraph"], cwd=ROOT, check=True)
    with tarfile.open(tar) as t:
        t.extractall(into, filter="data")
    return short


def run_worker(tree: Path, script: str, args: list[str], nice: int) -> list[dict]:
    """``bench/SCRIPT ARGS`` in a fresh process with ``tree``'s package first on the path
    (one BLAS thread, niceness ``nice``); its stdout's JSON lines. Raises RuntimeError
    with the tail of its stderr where it fails."""
    env = dict(os.environ, PYTHONPATH=str(tree), OMP_NUM_THREADS="1",
               OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
    cmd = ["nice", "-n", str(nice), sys.executable, str(HERE / script), *args]
    done = subprocess.run(cmd, env=env, capture_output=True, text=True, cwd=str(tree))
    if done.returncode:
        raise RuntimeError(f"{tree} {' '.join(args[:2])}: {done.stderr[-2000:]}")
    return [json.loads(line) for line in done.stdout.splitlines() if line.startswith("{")]
