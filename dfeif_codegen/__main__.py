"""`python -m dfeif_codegen`: the `codegen` command."""

import sys

from dfeif_codegen.cli import main

if __name__ == "__main__":
    sys.exit(main())
