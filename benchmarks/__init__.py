"""The scripts that print rigkit's published figures (index: benchmarks/README.md). Run
them from the checkout as modules: ``python -m benchmarks.NAME --help``."""
