"""printable: user-given names shown with every control character escaped, printable text kept."""

import pytest


@pytest.mark.parametrize(("raw", "shown"), [
    ("ev\x1b[31mil", "ev\\x1b[31mil"), ("bell\x07", "bell\\x07"), ("two\nlines\r", "two\\nlines\\r"),
    ("del\x7f", "del\\x7f"), ("csi\x9b2J", "csi\\x9b2J"), ("sep\u2028", "sep\\u2028"), ("µ = 0.5, ü", "µ = 0.5, ü"),
])
def test_printable_escapes_every_control_character(raw, shown):
    from packetloss_cvx.printable import printable
    assert printable(raw) == shown
