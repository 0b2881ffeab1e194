"""Where test_properties' time goes, per Hypothesis example: the engine, the draws, the body (docs/performance.md,
"Other benchmarks").

    OPENBLAS_NUM_THREADS=1 python benchmarks/property_examples.py [--tree PATH] [TEST_NAME ...]

Runs each property test of tests/lq/test_properties.py once under the root conftest's Hypothesis profile, with the
test's inner function wrapped (``test.hypothesis.inner_test``) to time its body, and the draws' product calls
(``random_system``, ``system_from_dict``) wrapped to time them; the rest is Hypothesis itself (generation,
mutation, the per-example PRNG save/restore, the composite strategy's own draws). CPU seconds
(time.process_time). Prints, per test, a SHA-256 prefix of every drawn example (the System's to_dict and the other
arguments, in order): two runs that print the same hash drew the same examples, so a change of settings or of the
product can be checked not to have changed what is tested. ``--tree`` runs another checkout (its tests and
package) in a fresh interpreter from that folder.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

SCRIPT = r"""
import hashlib, importlib.util, json, sys, time
sys.path.insert(0, "tests/lq")
spec = importlib.util.spec_from_file_location("root_conftest", "conftest.py")   # the Hypothesis profile
spec.loader.exec_module(importlib.util.module_from_spec(spec))
import test_properties as tp

names = json.loads(sys.argv[1]) or [n for n in dir(tp) if n.startswith("test_")]
product = {"t": 0.0}

def timed(fn, bucket):
    def wrapper(*args, **kwargs):
        t0 = time.process_time()
        try:
            return fn(*args, **kwargs)
        finally:
            bucket["t"] += time.process_time() - t0
    return wrapper

tp.random_system = timed(tp.random_system, product)
tp.system_from_dict = timed(tp.system_from_dict, product)
for name in names:
    test = getattr(tp, name)
    inner = test.hypothesis.inner_test
    body, digest, count = {"t": 0.0}, hashlib.sha256(), [0]
    timed_inner = timed(inner, body)

    def run(**kwargs):
        digest.update(repr([(k, v.to_dict() if hasattr(v, "to_dict") else v) for k, v in sorted(kwargs.items())])
                      .encode())
        count[0] += 1
        return timed_inner(**kwargs)

    test.hypothesis.inner_test = run
    product["t"] = 0.0
    t0 = time.process_time()
    test()
    total = time.process_time() - t0
    print(json.dumps({"test": name, "examples": count[0], "total": round(total, 3), "body": round(body["t"], 3),
                      "draws_product": round(product["t"], 3),
                      "hypothesis": round(total - body["t"] - product["t"], 3),
                      "examples_sha256": digest.hexdigest()[:16]}))
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("names", nargs="*", help="test names (default: every test of test_properties.py)")
    parser.add_argument("--tree", type=Path, default=ROOT, help="the checkout to run (default: this one)")
    args = parser.parse_args()
    import json

    env = dict(os.environ, PYTHONPATH=str(args.tree.resolve()))
    subprocess.run([sys.executable, "-c", SCRIPT, json.dumps(args.names)], cwd=args.tree, env=env, check=True)


if __name__ == "__main__":
    main()
