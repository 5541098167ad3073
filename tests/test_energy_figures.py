"""Seed 001's stick figures (Fig. 3/4 counterparts): labelled axes with units and a key."""

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from qmt_drake.energy.dynamics import ohsaka_arm  # noqa: E402
from qmt_drake.energy.figures import stick_figure  # noqa: E402
from qmt_drake.energy.fourier import FourierVelocityFamily  # noqa: E402


def test_stick_figure_has_units_and_a_key(tmp_path):
    fam = FourierVelocityFamily([0.1, -0.4, 0.9], 5)
    x = np.random.default_rng(0).normal(size=fam.n_genes) * 0.3
    x[-1] = 0.7  # T [s]
    fig, axs = plt.subplots(1, 2, figsize=(6, 3))
    stick_figure(axs[0], ohsaka_arm(), fam, x, title="with key")
    stick_figure(axs[1], ohsaka_arm(), fam, x, title="without", legend=False)
    for ax in axs:
        assert ax.get_xlabel() == "X1, horizontal [m]" and ax.get_ylabel() == "X2, up [m]"
    labels = [t.get_text() for t in axs[0].get_legend().get_texts()]
    assert labels[0] == "arm at t = 0" and "tip path" in labels and labels[1].startswith("arm at t = T = ")
    assert axs[1].get_legend() is None
    fig.tight_layout()
    fig.savefig(tmp_path / "stick.png", dpi=100)
    plt.close(fig)
