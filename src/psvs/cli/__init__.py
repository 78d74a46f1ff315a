"""The ``psvs`` command line: parses arguments, loads files, calls the library, writes the output."""
