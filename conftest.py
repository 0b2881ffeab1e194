# Root conftest: keep doctest collection away from the module entry point.
collect_ignore = ["packetloss_cvx/__main__.py"]
