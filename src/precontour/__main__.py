"""``python -m precontour`` runs the command-line interface."""

from .cli import main

# The guard keeps worker processes (``run`` checks on the virtual machine in two processes)
# from running the command again when they import this module.
if __name__ == "__main__":
    raise SystemExit(main())
