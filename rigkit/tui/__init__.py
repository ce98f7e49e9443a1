"""The field TUI (``rigkit field``): a guided three-position capture in a terminal.

The only part of rigkit that imports Textual (the layers contract in pyproject.toml
checks it). Everything it shows is computed by the library below it:
:mod:`rigkit.capture.field` (on-site checks), :mod:`rigkit.rangefinder.follow` (readings
across lost links), :mod:`rigkit.batch` (processing), :mod:`rigkit.reporting.verdict`.
"""
