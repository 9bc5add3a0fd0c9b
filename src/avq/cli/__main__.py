"""``python -m avq.cli``: the ``avq`` command."""

import sys

from avq.cli import main

sys.exit(main())
