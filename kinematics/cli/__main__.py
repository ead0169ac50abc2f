"""`python -m kinematics.cli` runs the command line; `--reference` alone prints docs/cli.md."""

import sys

from kinematics.cli.app import main, reference_markdown

if sys.argv[1:] == ["--reference"]:
    sys.stdout.write(reference_markdown())
    sys.exit(0)
sys.exit(main())
