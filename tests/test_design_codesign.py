"""Co-design arm family: at the thesis lengths the generated URDF is the committed ch.4 arm; scaled
links follow the uniform-density rule; a scenario written for new lengths loads."""

import re
from pathlib import Path

import numpy as np

from qmt_drake.design.codesign import ROOT, _arms, scaled_spec, write_scenario


def _body(text):
    # drop comment lines and the robot name, which name the source
    text = re.sub(r"<!--.*?-->", "", text)
    return re.sub(r'<robot name="[^"]*"', "<robot", text)


def test_thesis_lengths_reproduce_the_committed_urdf():
    gen = _arms().make_urdf("two_link_ch4", scaled_spec(0.160, 0.120))
    committed = (ROOT / "models" / "two_link_ch4.urdf").read_text()
    assert _body(gen) == _body(committed)


def test_scaling_rule_and_scenario(tmp_path):
    s = scaled_spec(0.20, 0.06)
    np.testing.assert_allclose(s["mass_kg"], [0.547 * 0.2 / 0.16, 0.146 * 0.06 / 0.12])
    np.testing.assert_allclose(s["izz_about_com_kgm2"], [2.440e-3 * (0.2 / 0.16) ** 3, 0.361e-3 * 0.5 ** 3])
    from qmt_drake.config.scenario import load_scenario
    p = write_scenario(0.18, 0.10, tmp_path)
    sc = load_scenario(p)
    assert Path(sc.urdf_path).name.startswith("two_link_ch4_l1_180mm_l2_100mm")
