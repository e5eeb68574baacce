"""The run's warm-up (`flight.run.runner.warm_up`) compiles, before the run takes the vehicle, every compiled kernel the
flight will call: a first call in flight costs seconds on a fresh install (the kernels' compilation), with the
thrusters holding their last command meanwhile."""

from __future__ import annotations

import subprocess
import sys

import pytest
from conftest import RUN_WARM_UP

pytestmark = pytest.mark.process      # starts a process or the bridge (tests/conftest.py)

PROBE = RUN_WARM_UP + """
from rov_mav.model import kernel
print(len(kernel.state_derivative.signatures), len(kernel.predict.signatures))
"""


@pytest.mark.parametrize("own", [False, True])
def test_the_run_s_own_estimators_model_is_compiled_before_the_flight_when_it_flies_on_it(own):
    """In a fresh interpreter: the law's and the prediction's kernels always; the model of `--estimator model`
    (kernel.state_derivative, which nothing else calls) only when the run will fly on it."""
    out = subprocess.run([sys.executable, "-c", PROBE.format(own=own)], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    own_estimator, predictor = map(int, out.stdout.split())
    assert predictor >= 1 and (own_estimator >= 1) == own
