"""The command-line tools, one module each, with one argument parser and one exit-code wrapper."""
