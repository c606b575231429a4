import sys

from boardproto.cli import main

sys.exit(main())
