"""``python -m appell``: the command line, as the ``appell`` script (:mod:`appell.io.cli`)."""

from appell.io.cli import main

if __name__ == "__main__":
    main()
