"""Benchmarks: ``python -m benchmarks.run_all`` (``make bench``) runs every ``bench_*.py``'s ``main()``.

Each module measures one part of the project and explains its figures; docs/performance.md records
them. ``rigctl bench <name>`` runs one of them from the command line.
"""
