"""Sub-commands of the ``realizer`` command line, one module each."""
