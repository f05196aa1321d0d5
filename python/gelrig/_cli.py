"""The ``gelrig`` command installed by the wheel: the same command as the Rust binary."""

import sys

from . import _gelrig


def main() -> None:
    sys.exit(_gelrig.cli(sys.argv))


if __name__ == "__main__":
    main()
