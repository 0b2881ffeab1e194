"""tests/processes.py, the Zygote the process tests fork their command-line runs from: a child's environment is its
own, except what an interpreter reads at start-up, which a fork cannot change (refused, not silently inherited)."""

import os
import subprocess
import sys

import pytest

from ..processes import Zygote


def test_a_forked_child_runs_with_its_own_environment_but_not_other_startup_variables():
    code = "import os, sys; print(os.environ.get('PLCVX_PROBE'), hash('packetloss'))"
    fresh = subprocess.run([sys.executable, "-c", code], env={**os.environ, "PYTHONHASHSEED": "7", "PLCVX_PROBE": "x"},
                           capture_output=True, text=True, check=True)
    with Zygote([], env={**os.environ, "PYTHONHASHSEED": "7"}) as zygote:
        child = zygote.run([], code=code, env={**zygote.env, "PLCVX_PROBE": "x"})
        assert (child.returncode, child.stdout) == (0, fresh.stdout)        # same seed: what a fresh run prints
        for name in ("PYTHONHASHSEED", "PYTHONPATH", "OPENBLAS_NUM_THREADS", "PACKETLOSS_CVX_BLAS_THREADS"):
            with pytest.raises(ValueError, match=name):                   # a fresh run would read another value
                zygote.start([], code=code, env={**zygote.env, name: zygote.env.get(name, "") + "8"})
        with pytest.raises(ValueError, match="PYTHONHASHSEED"):          # or none
            zygote.start([], code=code, env={k: v for k, v in zygote.env.items() if k != "PYTHONHASHSEED"})
