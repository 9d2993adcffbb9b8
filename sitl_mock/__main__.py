"""``python -m sitl_mock``: the same as the ``sitl-mock`` command."""

from sitl_mock.cli import entry_point

if __name__ == "__main__":
    entry_point()
