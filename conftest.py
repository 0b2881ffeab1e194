"""Root conftest: doctest collection, and one derandomised Hypothesis profile for every run.

CI and developers draw the same examples every time (``derandomize=True``), so a failure
seen once is seen again; ``--hypothesis-seed`` still explores on purpose.
"""

import os

# Hypothesis runs every installed "hypothesis" entry point when it is first imported; here that is trio's (a
# dependency of selenium), which imports trio (~0.14 s CPU in each of the three pytest processes, before the
# workers start) to make trio's own scheduler deterministic. No test uses trio or a Hypothesis plugin, so the
# suite imports Hypothesis without them; a value the user set is kept, and the children the tests start see the
# environment as it was.
_USER_PLUGINS = os.environ.get("HYPOTHESIS_NO_PLUGINS")
if _USER_PLUGINS is None:
    os.environ["HYPOTHESIS_NO_PLUGINS"] = "1"
try:
    from hypothesis import HealthCheck, settings
finally:
    if _USER_PLUGINS is None:
        del os.environ["HYPOTHESIS_NO_PLUGINS"]

collect_ignore = ["packetloss_cvx/__main__.py"]

settings.register_profile(
    "packetloss", derandomize=True, deadline=None, print_blob=True,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.load_profile("packetloss")
