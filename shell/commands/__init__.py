"""Verbs of the ``flexshell`` command line, one module per verb (see :mod:`shell.cli`)."""
