"""`python -m kinematics` runs the command line."""

import sys

from kinematics.cli import main

sys.exit(main())
