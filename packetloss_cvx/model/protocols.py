"""The two protocols and their validation."""

from __future__ import annotations

from ..errors import InputError

__all__ = ["PROTOCOLS", "check_protocol"]

PROTOCOLS = ("tcp", "udp")


def check_protocol(protocol: object, field: str = "protocol") -> str:
    """Return the protocol name, or raise [`InputError`][packetloss_cvx.errors.InputError] naming ``field``.

    Examples
    --------
    >>> check_protocol("udp")
    'udp'
    >>> check_protocol("tpc", field="--protocol")
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.InputError: --protocol: expected 'tcp' or 'udp', found 'tpc'
    """
    if protocol not in PROTOCOLS:
        raise InputError(field, f"expected 'tcp' or 'udp', found {protocol!r}")
    return str(protocol)
