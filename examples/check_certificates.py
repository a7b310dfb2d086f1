"""``switchest check``: a model's certificates as a picture
===========================================================

:func:`switchest.certify.certify` runs every check switchest can make of a model file
(observability, Lyapunov and joint-spectral-radius stability, mean-square stability, the
conditions of each paper's guarantee) and returns one :class:`~switchest.certify.Check` per
condition: a verdict (True, False, or None where it is inconclusive or does not apply) and,
where one is defined, a margin that is positive when the condition holds. ``switchest check
--model M.toml`` prints the same list. This example draws it for the smart-grid model of Zhang
& Natarajan (:func:`switchest.models.smart_grid`): margins as bars, right of zero where the
condition holds, and the verdicts without a margin as marks on the zero line.
"""

# %%
# Check the model
# ---------------
# The model files of every paper system are in ``examples/models/`` and in
# :func:`switchest.models.catalog.catalog`.
import matplotlib.pyplot as plt
import numpy as np

from switchest.certify import certify
from switchest.models.catalog import catalog

checks = certify(catalog()["zhang-smart-grid"])
for c in checks:
    verdict = {True: "holds", False: "fails", None: "n/a"}[c.verdict]
    margin = "" if c.margin is None else f"margin {c.margin:+.3g}"
    print(f"{c.name:55s} {verdict:6s} {margin}")

# %%
# Margins and verdicts
# --------------------
# Each margin is in the check's own unit (``1 - JSR``, a decay rate, a singular value), so
# the axis is logarithmic on both sides of zero.
colour = {True: "tab:green", False: "tab:red", None: "0.6"}
fig, ax = plt.subplots(figsize=(7.5, 0.32 * len(checks) + 1.2), layout="constrained")
rows = np.arange(len(checks))
for row, c in zip(rows, checks):
    if c.margin is not None:
        ax.barh(row, c.margin, color=colour[c.verdict], height=0.6)
    else:
        ax.plot(0, row, "D" if c.verdict is not None else "o", color=colour[c.verdict], ms=6)
ax.axvline(0, color="k", lw=0.8)
ax.set_xscale("symlog", linthresh=0.01)
ax.set_yticks(rows, [c.name for c in checks], fontsize=8)
ax.invert_yaxis()
ax.set_xlabel("margin (positive: the condition holds)")
handles = [plt.Rectangle((0, 0), 1, 1, color=colour[True]),
           plt.Rectangle((0, 0), 1, 1, color=colour[False]),
           plt.Line2D([], [], ls="", marker="D", color="k"),
           plt.Line2D([], [], ls="", marker="o", color=colour[None])]
fig.legend(handles, ["holds", "fails", "verdict without a margin (colour: verdict)",
                     "not applicable or inconclusive"], loc="outside lower center", ncols=2,
           fontsize=7, frameon=False)
ax.set_title("switchest check: zhang-smart-grid", fontsize=9)
