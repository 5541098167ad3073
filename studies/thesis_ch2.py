"""Seed 000 chapter 2: reported genes, GA over 10 seeds, family optimum, figures -> out/thesis-ch2/.

Run: .venv/bin/python -m studies.thesis_ch2 [--out out] [--seeds 10] [--workers 2]
"""

import sys

from qmt_drake.apps.thesis_study import main

if __name__ == "__main__":
    sys.exit(main("thesis-ch2"))
