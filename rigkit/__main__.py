import sys

from rigkit.cli import main

sys.exit(main())
