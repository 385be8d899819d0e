"""Exchange of measured runs with the outside world: the CSV format, and loading runs from paths."""

from rigctl.io.csv_format import read_csv, write_csv
from rigctl.io.load import expand_paths, load_run, load_runs

__all__ = ["expand_paths", "load_run", "load_runs", "read_csv", "write_csv"]
