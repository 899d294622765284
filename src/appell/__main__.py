"""``python -m appell``: the command line, as the ``appell`` script (:mod:`appell_entry`,
:mod:`appell.io.cli`)."""

import sys

from appell_entry import main

if __name__ == "__main__":
    sys.exit(main())
