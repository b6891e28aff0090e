"""
A sweep and its comparison sheet
================================

``psbench -m`` runs one job per combination of the swept parameters, stores each row in
the Parquet store, prints a summary table (best first) and writes a comparison sheet: one
column per run with its input, ground truth, normals and NE map. Here least squares and
the mask combination ``Th-Hi-Re-Sh`` at two source zeniths, at 64 x 64 pixels, into a
throwaway store (``PSBENCH_RESULTS``).
"""
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt

store = Path(tempfile.mkdtemp(prefix="psbench-sweep-"))
psbench = str(Path(sys.executable).parent / "psbench")
cmd = [psbench, "-m", "mask=None,Th-Hi-Re-Sh", "zenith=30,60", "size=64",
       "sweep=masks_by_zenith"]
print("$", " ".join(["psbench"] + cmd[1:]))
out = subprocess.run(cmd, env={**os.environ, "PSBENCH_RESULTS": str(store)}, cwd=store,
                     text=True, capture_output=True, check=True).stdout
print(out.split("\n\nsweep ", 1)[-1].replace(str(store), "…") if "\n\nsweep " in out else out)

# %%
# The sheet ``comparison.png`` (``comparison.html`` beside it links every run's pictures)
sheet = plt.imread(store / "out" / "masks_by_zenith" / "comparison.png")
fig = plt.figure(figsize=(10, 10 * sheet.shape[0] / sheet.shape[1]))
ax = fig.add_axes([0, 0, 1, 1])
ax.imshow(sheet)
_ = ax.axis("off")

# %%
# The same rows, read back from the store with pandas
from psbench.harness import read_store

rows = read_store(store)
print(rows[["mask", "lights", "ne_mean", "ie_rel", "qf_total"]]
      .sort_values(["lights", "ne_mean"]).to_string(index=False))
