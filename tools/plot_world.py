"""Draw the world frame with the four catalog tables and the robot base (docs/world_frame.png)."""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from slide_gym.geometry import TABLE_NAMES, get_table  # noqa: E402
from slide_gym.task import REACH_MAX, REACH_MIN  # noqa: E402


def main(out: Path) -> None:
    fig, ax = plt.subplots(figsize=(6.4, 5.2))
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for name, color in zip(TABLE_NAMES, colors, strict=False):
        xs, ys = get_table(name).polygon.exterior.xy
        ax.plot(xs, ys, color=color, label=f"table '{name}'")
    theta = np.linspace(-np.pi / 2, np.pi / 2, 200)
    for r in (REACH_MIN, REACH_MAX):
        ax.plot(r * np.cos(theta), r * np.sin(theta), "k:", lw=0.8)
    ax.text(REACH_MAX * 0.72, -REACH_MAX * 0.74, "object reach limits", fontsize=8)
    ax.add_patch(plt.Rectangle((-0.18, -0.14), 0.36, 0.28, color="0.6", alpha=0.5))
    ax.annotate("", (0.25, 0), (0, 0), arrowprops={"arrowstyle": "->", "color": "r", "lw": 2})
    ax.annotate("", (0, 0.25), (0, 0), arrowprops={"arrowstyle": "->", "color": "g", "lw": 2})
    ax.text(0.26, 0.01, "x", color="r")
    ax.text(0.01, 0.26, "y", color="g")
    ax.text(-0.19, -0.27, "WAM base at the origin,\nz up, shoulder z = 0.346 m", fontsize=8)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title("slide-gym world frame, top view (table tops at z = 0)")
    ax.legend(loc="upper left", fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("docs/world_frame.png"))
