"""What every layer of psbench uses and none owns: argument checks (``checks``),
deprecated names (``deprecation``), atomic file writes (``files``), how solves map
memory (``memory``), provenance of the code (``provenance``) and numba's threading
set-up (``numba_setup``). Private: the public error type is re-exported as
:class:`psbench.PsbenchError`."""
