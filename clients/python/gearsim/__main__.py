# SPDX-License-Identifier: MIT
"""`python3 -m gearsim ...`: the same as gearctl."""
import sys

from .cli import main

if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
