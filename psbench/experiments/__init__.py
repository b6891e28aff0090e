"""Thesis experiments, one module each, with the grid YAML beside it.

An experiment is everything about one thesis table or figure in one place: the runs it
needs (its grid, ``<name>.yaml``) and, in ``<name>.py``, what its report page says and
decides. ``psbench +experiment=<name>`` runs the grid; ``psbench-report`` aggregates the
stored rows, puts them beside the thesis's values, decides the verdicts and draws the
figures; the CI gate (``python -m psbench.report.gate``) compares the aggregates of the
gated experiments with committed baselines. None of them holds a list of experiments:
they find them through :func:`psbench.registry.experiments`.

Adding an experiment
--------------------
Write two files side by side, ``mypkg/myexp.py`` and ``mypkg/myexp.yaml``, and register
the module under the entry-point group ``psbench.experiments`` in your package's
``pyproject.toml`` (psbench registers its own the same way)::

    [project.entry-points."psbench.experiments"]
    myexp = "mypkg.myexp"

    [tool.setuptools.package-data]
    mypkg = ["*.yaml"]

then ``pip install -e .``. In a notebook or a test, ``psbench.registry.register(
"experiments", module)`` registers a module for the running process. A module added to
this package is found by convention as well when psbench runs from a source tree without
installed metadata.

The grid (``<name>.yaml``)
--------------------------
::

    experiment:
      name: myexp                      # = the registered name; the store folder
      description: "one line for the report page"
      grids:                           # union of cartesian products of run parameters
        - {surface: [semisphere, sombrero], mask: [None, Th], noise: [0.0, 0.1]}
      fixed: {lights: 45x8, model: ts}
      scales:                          # psbench +experiment=myexp scale=ci
        full: {size: 512, seed: [0]}
        ci: {size: 32, seed: [0]}

Keys of ``grids``/``fixed``/``scales`` are run parameters (``psbench --help``); values
may use ``${oc.env:VAR,default}`` and ``${results_dir}`` (the results store). See
:mod:`psbench.harness.grid` for the expansion rules.

The module contract
-------------------
Required:

TITLE : str
    Page title, e.g. ``"Table 5.3: overall results of all masks"``.
aggregate(rows) -> pandas.DataFrame
    Reduce the experiment's ok rows of the store (one row per run, the columns of
    :mod:`psbench.harness.schema`) to the long format ``experiment, part, row, column,
    value, n`` (``n`` = runs averaged; ``part`` is ``""`` for one-part tables). Keys are
    strings and match those of ``THESIS`` for the same cell. Build it with
    :func:`psbench.report.aggregates.long_frame` from ``(part, row, column, value, n)``
    tuples; ``rows`` is never empty when called.

Expected (each has a neutral default when absent):

AVERAGES : str
    Plain-language statement of what psbench's numbers average (shown on the page).
NOTES : str
    Deviations from the thesis and caveats (``""``: none beyond the image size).
THESIS : dict
    The thesis's values of the same cells, ``{part: {row: {column: value}}}`` (``None``
    for the thesis's "N/A"); the page shows psbench, thesis and their difference in
    separate columns.
verdicts(agg, rows) -> list of Verdict
    One :class:`psbench.report.verdicts.Verdict` per qualitative conclusion of the
    thesis, decided on the aggregate with the shared rules of
    :mod:`psbench.report.verdicts` (``verdict``, ``lowest``, ``nodata``, the
    ``NE_MARGIN`` below which a difference is INCONCLUSIVE). Must not raise on an empty
    aggregate: missing data is INCONCLUSIVE. List the thesis's main conclusion first:
    the index shows each experiment's first verdict among its key findings.
figures(agg) -> list of (str, matplotlib.figure.Figure)
    ``(file stem, figure)`` pairs; import :mod:`psbench.report.figures` (helpers
    ``new_figure``, ``line``, ``thesis``, ``finish``, ``figure_legend``) inside the
    function, so that running the grid never imports matplotlib. Label the axes with
    units and the thesis's values as such (``thesis(ax, x, y)``). A module that draws
    from the results rows too (e.g. the per-pixel maps of the ``ne_map`` extra) declares
    ``figures(agg, rows=None)``: the report then passes the experiment's ok rows as
    ``rows=`` (a DataFrame of the store's columns); it must still draw from ``agg``
    alone when ``rows`` is None.
GATED : bool
    Whether the CI gate runs it at ``scale=ci`` and checks its aggregate (default
    False; a gated experiment needs a baseline, ``python -m psbench.report.gate update
    --only <name>``).

Optional:

prepare(root, scale) -> None
    Called by ``psbench +experiment=<name>`` before its runs, with the results folder and
    the scale: makes generated inputs the grid refers to (e.g. simulated captures under
    ``${results_dir}``) when they are missing. Must be idempotent and write atomically.
cell_kind(part, column) -> str
    Tolerance class of a cell in the CI gate (``ne``, ``cond``, ``qf``, ``ie``,
    ``percent``, ``time``, ``threshold``, ``ratio``; default ``ne``).
IN_TOTALS : bool
    Whether the report index counts this experiment's verdicts in its totals (default
    True; False for an experiment that re-decides other pages' claims, such as
    ``interpretations``).
HIDDEN_PARTS : set of str
    Parts too long for a page table (plotted and listed in ``data/<name>.csv`` only).
cell_unit(part, column) -> str, column_label(part, column) -> str, TABLE_AXES, PART_TITLES
    Presentation of the page's tables: a cell's unit (default from ``cell_kind``: deg,
    %, s, ...), a column's header, ``{part: (rows title, columns title)}`` and ``{part:
    heading}`` (see :mod:`psbench.report.present`).

Example
-------
A complete experiment, ``mypkg/noise_sweep.py`` (its YAML as above, ``name:
noise_sweep``)::

    from psbench.report.aggregates import group_mean, fmt_num, long_frame, lookup
    from psbench.report.verdicts import NE_MARGIN, num, verdict

    TITLE = "NE of Th vs noise"
    AVERAGES = "Mean NE over the surfaces of the grid."
    NOTES = ""
    THESIS = {"": {"Th": {"0": 2.0}}}
    GATED = False

    def aggregate(rows):
        recs = []
        group_mean(rows, ["mask", "noise"], "ne_mean", recs, lambda k: "",
                   lambda k: k[0], lambda k: fmt_num(k[1]))
        return long_frame(recs)

    def verdicts(agg, rows=None):
        a, b = lookup(agg, "", "Th", "0"), lookup(agg, "", "Th", "0.1")
        return [verdict("Noise raises the NE of Th", b > a if a == a and b == b else None,
                        f"{num(a)} -> {num(b)} deg", undecided=abs(b - a) < NE_MARGIN)]

    def figures(agg):
        from psbench.report.figures import finish, line, new_figure
        fig, (ax,) = new_figure()
        line(ax, agg, "", "Th")
        finish(ax, "noise", "NE (deg)")
        return [("noise_sweep", fig)]
"""
