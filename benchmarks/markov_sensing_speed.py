"""Issue 19 item 6 (the test suite's time), the Markov, sensing and closed-loop kernels the slow tests exercise:
each case at this checkout and at a baseline checkout, side by side in one run. Every case runs in a fresh
interpreter per checkout (imports excluded from the timing), the checkouts interleaved, ``--repeat`` rounds;
CPU seconds (time.process_time, one BLAS thread), the minimum per checkout, their ratio, and whether the two
results print the same (``repr`` of the answer: the speed-ups must not change a number).

    OPENBLAS_NUM_THREADS=1 PYTHONPATH=$PWD python benchmarks/markov_sensing_speed.py [--baseline /work/base/e520261]
        [--repeat 3] [--case NAME ...]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

#: name -> (setup, the timed statement assigning ``result``); setup is not timed
CASES = {
    "critical_gamma, two channels (test_sensing_estimation)": (
        "import numpy as np\n"
        "from packetloss_cvx.sensing.bounds import critical_gamma\n"
        "from packetloss_cvx.model.sensor import Sensor\n"
        "A = np.array([[1.5, 0.1], [0.0, 0.3]])\n"
        "sensor = Sensor(C=[[1.0, 0.0], [0.0, 1.0]], gamma=[0.5, 0.5], groups=[[0], [1]], noise_cov=np.eye(2))\n",
        "cg = critical_gamma(A, sensor)\nresult = (cg.lower, cg.upper, cg.exact)"),
    "critical_gamma, pendulum_sensor": (
        "from packetloss_cvx.model.files import load_example\n"
        "from packetloss_cvx.sensing.bounds import critical_gamma\n"
        "s = load_example('pendulum_sensor')\n",
        "cg = critical_gamma(s.A, s.sensor)\nresult = (cg.lower, cg.upper, cg.exact)"),
    "simulate, N = 1000 bursty chain, 4000 runs (test_simulate_markov, seed 322)": (
        "import numpy as np\n"
        "from packetloss_cvx.model.channel import GilbertElliott\n"
        "from packetloss_cvx.model.chain import attach_channel\n"
        "from packetloss_cvx.model.random_systems import random_system\n"
        "from packetloss_cvx.montecarlo.simulate import simulate\n"
        "rng = np.random.default_rng(322)\n"
        "s = random_system(rng, n=3, m=2, horizon=1000, spectral_radius=0.97, non_stationary=False, noise=False,\n"
        "                  edge_mu=False, time_varying=False)\n"
        "lam, rate = rng.uniform(0.5, 0.9, 2), rng.uniform(0.6, 0.9, 2)\n"
        "h = {'h_good': rng.uniform(0.9, 1.0, 2), 'h_bad': rng.uniform(0.0, 0.2, 2)}\n"
        "s = attach_channel(s, GilbertElliott(p=(1 - rate) * (1 - lam), r=rate * (1 - lam), belief=[0.2, 0.9], **h))\n",
        "sim = simulate(s, 4000, seed=322, laws=['tcp', 'udp'], progress=False)\n"
        "result = sorted((k, v.mean, v.stderr, v.exact) for k, v in sim.open_loop.items())"),
    "simulate, N = 1000 Gilbert chain (outcomes reveal the state), 4000 runs (test_simulate_markov, seed 321)": (
        "import numpy as np\n"
        "from packetloss_cvx.model.channel import GilbertElliott\n"
        "from packetloss_cvx.model.chain import attach_channel\n"
        "from packetloss_cvx.model.random_systems import random_system\n"
        "from packetloss_cvx.montecarlo.simulate import simulate\n"
        "rng = np.random.default_rng(321)\n"
        "s = random_system(rng, n=3, m=2, horizon=1000, spectral_radius=0.97, non_stationary=False, noise=False,\n"
        "                  edge_mu=False, time_varying=False)\n"
        "lam, rate = rng.uniform(0.5, 0.9, 2), rng.uniform(0.6, 0.9, 2)\n"
        "s = attach_channel(s, GilbertElliott(p=(1 - rate) * (1 - lam), r=rate * (1 - lam)))\n",
        "sim = simulate(s, 4000, seed=321, laws=['tcp', 'udp'], progress=False)\n"
        "result = sorted((k, v.mean, v.stderr, v.exact) for k, v in sim.open_loop.items())"),
    "region --law dp --sensor-grid 4, scalar sensor file (test_sensing_cli)": (
        "import tempfile\n"
        "from pathlib import Path\n"
        "from packetloss_cvx.cli.parser import build_parser\n"
        "from packetloss_cvx.cli.region import run\n"
        "from packetloss_cvx.model.files import save_system\n"
        "from packetloss_cvx.model.system import System\n"
        "from packetloss_cvx.model.sensor import Sensor\n"
        "s = System(A=[[2.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[0.9], x0=[1.0],\n"
        "           noise_cov=[[1.0]], sensor=Sensor(C=[[1.0]], gamma=[0.9]))\n"
        "folder = tempfile.TemporaryDirectory()\n"
        "path = str(save_system(s, Path(folder.name) / 'scalar.toml'))\n"
        "args = build_parser().parse_args(['region', path, '--law', 'dp', '--sensor-grid', '4', '-q'])\n",
        "result = run(args).data"),
    "simulate pendulum_bursty --closed-loop, 20000 runs x 25 steps": (
        "from packetloss_cvx.model.files import load_example\n"
        "from packetloss_cvx.montecarlo.simulate import simulate\n"
        "s = load_example('pendulum_bursty')\n",
        "sim = simulate(s, 20000, steps=25, seed=311, closed_loop=True, progress=False)\n"
        "result = sorted((k, v.mean_stage_cost, v.stderr) for k, v in sim.closed_loop.items())"),
}

CHILD = """
import json, sys, time
setup, stmt = json.loads(sys.argv[1])
scope = {{}}
exec(setup, scope)
start = time.process_time()
exec(stmt, scope)
print(json.dumps([time.process_time() - start, repr(scope["result"])]))
"""


def run_case(root: Path, name: str) -> tuple[float, str]:
    env = dict(os.environ, PYTHONPATH=str(root), OPENBLAS_NUM_THREADS="1")
    out = subprocess.run([sys.executable, "-c", CHILD.format(), json.dumps(CASES[name])], env=env, cwd=str(root),
                         capture_output=True, text=True, check=True)
    seconds, text = json.loads(out.stdout.strip().splitlines()[-1])
    return seconds, text


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", type=Path, default=Path("/work/base/e520261"))
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--case", action="append", help="a case name prefix (repeatable); default every case")
    args = parser.parse_args()
    names = [n for n in CASES if not args.case or any(n.startswith(c) for c in args.case)]
    print(f"| case | {args.baseline.name} CPU s | this CPU s | ratio | same result |")
    print("|---|---|---|---|---|")
    for name in names:
        base, this, texts = [], [], set()
        for _ in range(args.repeat):
            for root, times in ((args.baseline, base), (ROOT, this)):
                seconds, text = run_case(root, name)
                times.append(seconds)
                texts.add(text)
        print(f"| {name} | {min(base):.3f} | {min(this):.3f} | {min(base) / min(this):.2f} | "
              f"{'yes' if len(texts) == 1 else 'NO'} |", flush=True)


if __name__ == "__main__":
    main()
