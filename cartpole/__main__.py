"""``python -m cartpole`` is the ``cartpole`` command."""
import sys

from cartpole.cli import main

sys.exit(main())
