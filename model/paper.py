"""The 2002 correlator's reference figures (Nygren, FOI-R--0764--SE, section 8.3), in one place.

The benchmarks compare against them and the synthesis flow sizes its builds from them; neither owns them.
"""

from __future__ import annotations

__all__ = ["PAPER_MAP_SHAPE", "PAPER_PATCH_SHAPE", "PAPER_SECONDS"]

#: The paper's sizes: a 501 x 501 map and a 10 x 10 sonar patch.
PAPER_MAP_SHAPE = (501, 501)
PAPER_PATCH_SHAPE = (10, 10)
#: The 2002 hardware correlator's time for one correlation at the paper's sizes.
PAPER_SECONDS = 0.266
