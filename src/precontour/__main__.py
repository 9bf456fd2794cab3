"""``python -m precontour`` (and the ``precontour`` command) run the command-line interface.

:func:`main` imports the interface only when called, so that Ctrl-C while the numerical
libraries load (the first second or more) ends in one line, ``precontour: interrupted``, as
it does later, instead of a traceback from inside an import.
"""

import sys


def main(argv: list[str] | None = None) -> int:
    try:
        from .cli import main as cli_main

        return cli_main(argv)
    except KeyboardInterrupt:
        print("precontour: interrupted", file=sys.stderr)
        return 130


# The guard keeps worker processes (``run`` checks on the virtual machine in two processes)
# from running the command again when they import this module.
if __name__ == "__main__":
    raise SystemExit(main())
