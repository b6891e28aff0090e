"""Benchmark harness: Hydra app (``psbench``), the run spec (every run parameter declared
once, :mod:`psbench.harness.spec`), runs, Parquet results store, experiment grids and
sharded execution, ``psbench-results`` maintenance CLI.

``read_store`` is the reader used by reports::

    from psbench.harness import read_store
    df = read_store("results", experiment="table5_3")
"""
from .schema import SCHEMA, SCHEMA_VERSION
from .store import compact, read_store

__all__ = ["read_store", "compact", "SCHEMA", "SCHEMA_VERSION"]
