import sys

from imugen.cli import main

sys.exit(main())
