"""What the controllability staircase drops and keeps by rounding (tolerances.CONTROLLABILITY_RTOL's measurement).

Run under each kernel, e.g.
`for k in Haswell Prescott SkylakeX; do OPENBLAS_CORETYPE=$k python benchmarks/controllability.py; done`.
Plants with a planted uncontrollable part (dimension nc of n <= 12) rotated by a random orthogonal matrix. Prints
how many splits differ from the planted dimension (a random reached part can itself be near uncontrollable), the
largest singular value dropped and the least kept, both relative to ||[A, B]||_2.
"""

import numpy as np
from scipy.stats import ortho_group

from packetloss_cvx.linalg import controllable_split


def main(cases: int = 2000, seed: int = 0) -> None:
    rng = np.random.default_rng(seed)
    worst_dropped, least_kept, differ = 0.0, np.inf, 0
    for _ in range(cases):
        n = int(rng.integers(1, 13))
        nc = int(rng.integers(0, n + 1))
        m = int(rng.integers(1, 4))
        A = rng.normal(size=(n, n))
        A[nc:, :nc] = 0.0
        B = rng.normal(size=(n, m))
        B[nc:] = 0.0
        Q = ortho_group.rvs(n, random_state=rng) if n > 1 else np.eye(1)
        split = controllable_split(Q @ A @ Q.T, Q @ B)
        differ += split.nc != nc
        worst_dropped = max(worst_dropped, split.dropped)
        least_kept = min(least_kept, split.kept)
    print(f"{cases} plants: {differ} differ from the planted split; largest dropped {worst_dropped:.2e}, "
          f"least kept {least_kept:.2e} (relative to ||[A, B]||)")


if __name__ == "__main__":
    main()
