"""``python -m packetloss_cvx``."""

import sys

from .cli import main

sys.exit(main())
