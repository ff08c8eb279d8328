"""The ``rover`` command: argument parsing only; the work happens in the packages."""
