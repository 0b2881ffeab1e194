"""Lossy sensor links: the Kalman filter with intermittent observations (kalman), bounds on its
expected error covariance and critical arrival rate (bounds, lmi), the loop (x, xhat) under both protocols
with an estimated state (loop) and its Monte Carlo (montecarlo). The sensor itself is ``packetloss_cvx.model.sensor``.
"""
