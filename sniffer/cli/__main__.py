"""Provides `python -m sniffer.cli`, the same as the `modscope` command."""

import sys

from sniffer.cli import main

sys.exit(main())
