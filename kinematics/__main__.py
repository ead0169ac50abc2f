"""`python -m kinematics` runs the command line."""

from kinematics.cli import run

run()
