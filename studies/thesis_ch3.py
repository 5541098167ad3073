"""Seed 000 chapter 3: reported genes, GA over 10 seeds, family optimum, figures -> out/thesis-ch3/.

Run: .venv/bin/python -m studies.thesis_ch3 [--out out] [--seeds 10] [--workers 2]
"""

import sys

from qmt_drake.apps.thesis_study import main

if __name__ == "__main__":
    sys.exit(main("thesis-ch3"))
