"""``python -m attica``: the same as the ``attica`` command."""

import sys

from attica.cli import main

sys.exit(main())
