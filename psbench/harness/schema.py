"""The results row schema: the single source of truth for the Parquet store.

One row per run. Column groups:

- identity: ``run_id`` (hash of the resolved run parameters), ``sweep`` (the store
  folder: experiment name or ``sweep=`` name), ``experiment`` (or null), ``kind``;
- parameters (:data:`PARAM_COLUMNS`: every run parameter of the run spec
  :mod:`psbench.harness.spec`, then ``n_images``); ``shadows`` is True for cast + self
  shadows, False otherwise (render's "self" and "none"; the exact value is in
  ``config``); mappings and lists (``options``, ``thresholds``, ``args``, ``extras``)
  are json text with sorted keys, null when empty;
- metrics (:data:`METRIC_COLUMNS`), ``qf_sr`` the QF of the masked observations
  against those of true secondary fraction above ``t_sr`` (scenes rendered with
  ``bounces`` > 0), ``ve_mean`` / ``ve_median`` the mean and median of the
  ground-truth-free validation error map (``Result.ve``, :mod:`psbench.solve.validation`;
  relative to each pixel's mean intensity), ``fallback_fraction`` the fraction of the
  object pixels where the method fell back to its simpler answer (``Result.fallback``,
  :mod:`psbench.solve.fallback`; null for methods without the fallback), NE fractions ``ne_lt*`` in 0..1, ``ie_rel`` in % of
  the images' dynamic range, ``ie_weighted`` the ring-weighted IE (Eq. 2.30, L2) of
  ``method=wps`` runs, times in seconds (``t_render``: render or read the images,
  0 when the scene came from the chunk's cache; ``t_solve``: the solve, after an
  untimed warm-up solve of a 16 x 16 crop that loads compiled kernels; ``t_total``: the whole run; ``t_cpu``: CPU seconds of the process during the run, a
  load-independent cost figure), ``peak_mem_mb`` the peak resident set of
  the process that ran the run (reset before each run where Linux allows it);
- payloads: json strings (``ne_by_zenith``, ``payload`` of analysis runs); ``ne_map``
  the per-pixel NE map of the ``ne_map`` extra (base64 16-bit PNG,
  :mod:`psbench.harness.nemap`);
- status: ``status`` ("ok" / "failed"), ``error``, ``traceback`` (last frames);
- provenance: ``schema_version``, ``psbench_version``, ``git_sha``, ``git_dirty``,
  ``libs`` (json), ``host``, ``utc``, ``config`` (json of the full run config).

Bump :data:`SCHEMA_VERSION` when columns change meaning; readers fill columns missing
from older files with nulls.
"""
from __future__ import annotations

import pyarrow as pa

from .spec import columns

__all__ = ["SCHEMA_VERSION", "SCHEMA", "COLUMNS", "PARAM_COLUMNS", "METRIC_COLUMNS",
           "META_KEY", "empty_table", "row_table"]

SCHEMA_VERSION = 1
META_KEY = b"psbench.schema_version"

# parameter columns come from the run spec (one declaration per parameter); n_images is
# derived from the scene
_PARAMS = [(n, pa.type_for_alias(t)) for n, t in columns()] + [("n_images", pa.int64())]
_METRICS = [
    ("ne_mean", pa.float64()),
    ("ne_median", pa.float64()),
    ("ne_lt5", pa.float64()),
    ("ne_lt10", pa.float64()),
    ("ne_lt20", pa.float64()),
    ("ie_l1", pa.float64()),
    ("ie_l2", pa.float64()),
    ("ie_linf", pa.float64()),
    ("ie_rel", pa.float64()),
    ("ie_weighted", pa.float64()),
    ("qf_hi", pa.float64()),
    ("qf_sh", pa.float64()),
    ("qf_total", pa.float64()),
    ("qf_sr", pa.float64()),
    ("cond", pa.float64()),
    ("ve_mean", pa.float64()),
    ("ve_median", pa.float64()),
    ("fallback_fraction", pa.float64()),
    ("t_render", pa.float64()),
    ("t_solve", pa.float64()),
    ("t_total", pa.float64()),
    ("t_cpu", pa.float64()),
    ("peak_mem_mb", pa.float64()),
]
_FIELDS = (
    [("run_id", pa.string()), ("sweep", pa.string()), ("experiment", pa.string())]
    + _PARAMS + _METRICS
    + [("ne_by_zenith", pa.string()), ("ne_map", pa.string()), ("payload", pa.string()),
       ("status", pa.string()), ("error", pa.string()), ("traceback", pa.string()),
       ("schema_version", pa.int32()), ("psbench_version", pa.string()),
       ("git_sha", pa.string()), ("git_dirty", pa.bool_()), ("libs", pa.string()),
       ("host", pa.string()), ("utc", pa.timestamp("us", tz="UTC")), ("config", pa.string())]
)

SCHEMA = pa.schema([pa.field(n, t) for n, t in _FIELDS],
                   metadata={META_KEY: str(SCHEMA_VERSION).encode()})
COLUMNS = tuple(SCHEMA.names)
PARAM_COLUMNS = tuple(n for n, _ in _PARAMS)
METRIC_COLUMNS = tuple(n for n, _ in _METRICS)
REQUIRED = ("run_id", "sweep", "status", "schema_version", "utc")


def empty_table() -> pa.Table:
    """A zero-row table with :data:`SCHEMA`."""
    return SCHEMA.empty_table()


def row_table(rows) -> pa.Table:
    """Build a table with :data:`SCHEMA` from dicts (missing keys -> null).

    Raises
    ------
    PsbenchError
        When a dict holds a key that is not a column.
    """
    from .._shared.checks import PsbenchError

    rows = list(rows)
    for r in rows:
        extra = set(r) - set(COLUMNS)
        if extra:
            raise PsbenchError(f"row has unknown columns {sorted(extra)}; "
                               f"valid columns: {', '.join(COLUMNS)}")
    cols = {n: [r.get(n) for r in rows] for n in COLUMNS}
    return pa.Table.from_pydict(cols, schema=SCHEMA)


def conform(table: pa.Table) -> pa.Table:
    """Cast a table read from disk to :data:`SCHEMA` (missing columns -> null,
    unknown columns dropped). Raises on incompatible types."""
    n = table.num_rows
    arrays = []
    for f in SCHEMA:
        if f.name in table.column_names:
            col = table.column(f.name)
            if col.type != f.type:
                col = col.cast(f.type)
            arrays.append(col)
        else:
            arrays.append(pa.nulls(n, type=f.type))
    return pa.Table.from_arrays(arrays, schema=SCHEMA)
