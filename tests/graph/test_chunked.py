"""The chunk jobs' runner of long videos (mirrorgraph.graph.chunked._Runner)."""

from __future__ import annotations

import os
import time
from dataclasses import dataclass

import pytest

from mirrorgraph.graph.chunked import _Runner


@dataclass
class _Done:
    index: int
    pid: int
    final_error: float


def _job(i: int) -> _Done:
    time.sleep(0.02 * (i % 3))                 # uneven jobs
    if i == 7:
        raise ValueError("job 7 failed")
    return _Done(i, os.getpid(), float(i))


@pytest.mark.parametrize("workers", [1, 2])
def test_results_in_the_jobs_order_from_every_process(workers):
    runner = _Runner(workers)
    try:
        seen: list[int] = []
        out = runner.map(_job, list(range(7)), lambda k, _: seen.append(k))
    finally:
        runner.close()
    assert [r.index for r in out] == list(range(7))
    assert seen == list(range(1, 8))                  # reported once each, in order
    assert len({r.pid for r in out}) == workers


def test_a_failed_job_is_raised():
    runner = _Runner(2)
    try:
        with pytest.raises(ValueError, match="job 7"):
            runner.map(_job, list(range(12)), None)
    finally:
        runner.close()
