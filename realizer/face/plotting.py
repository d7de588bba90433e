"""Plots of FAP tracks over time, with the sync points that shape them.

Used by ``realizer plot-faps``. Angular FAPs (eyeballs 23-26 and head 48-50,
in angle units of 1e-5 rad) are drawn on their own axes below the others
(FAPU-scaled displacements), because their values are two orders larger.
Matplotlib is imported inside the function, with the non-interactive Agg
back end, so importing this module costs nothing.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import numpy.typing as npt

#: FAPs measured in angle units (Tekalp and Ostermann 2000, Table 7, unit "AU").
ANGULAR_FAPS = frozenset({23, 24, 25, 26, 47, 48, 49, 50})


def plot_fap_tracks(
    times: npt.NDArray[np.float64],
    values: npt.NDArray[np.float64],
    mask: npt.NDArray[np.bool_],
    syncs: Sequence[tuple[str, float]],
    path: str | Path,
    *,
    title: str = "",
    names: Sequence[str] | None = None,
) -> tuple[int, ...]:
    """Plot every FAP set at some frame; ``times`` (n,) seconds, ``values`` and
    ``mask`` (n, 68); ``syncs`` (label, seconds) become vertical lines. Writes
    ``path`` (PNG) and returns the FAP numbers drawn."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    used = [int(i) + 1 for i in np.flatnonzero(mask.any(axis=0))]
    linear = [fap for fap in used if fap not in ANGULAR_FAPS]
    angular = [fap for fap in used if fap in ANGULAR_FAPS]
    groups = [g for g in (linear, angular) if g] or [[]]
    figure, axes = plt.subplots(
        len(groups), 1, figsize=(11, 3.6 * len(groups)), sharex=True, squeeze=False
    )
    for axis, group in zip(axes[:, 0], groups, strict=True):
        for fap in group:
            label = f"{fap} {names[fap - 1]}" if names else f"FAP {fap}"
            axis.plot(times, np.where(mask[:, fap - 1], values[:, fap - 1], np.nan), label=label)
        unit = "angle units (1e-5 rad)" if group and group[0] in ANGULAR_FAPS else "FAPU units"
        axis.set_ylabel(unit)
        axis.grid(True, alpha=0.3)
        if group:
            axis.legend(fontsize=7, ncol=3, loc="upper right")
        for _label, moment in syncs:
            axis.axvline(moment, color="0.55", linestyle="--", linewidth=0.7)
    top = axes[0, 0]
    high = top.get_ylim()[1]
    for label, moment in syncs:
        top.text(moment, high, label, rotation=90, fontsize=6, va="top", ha="right", color="0.35")
    axes[-1, 0].set_xlabel("time (s)")
    if title:
        top.set_title(title)
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)
    return tuple(used)
