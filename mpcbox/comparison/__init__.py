"""Comparisons of controllers over scenarios and seeds: runner, tables, plots and push limits."""
