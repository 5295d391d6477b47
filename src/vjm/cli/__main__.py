"""``python -m vjm.cli``: the ``vjm`` command."""
import sys

from . import main

sys.exit(main())
