"""The target calibration's choices and defaults, in a module that imports nothing.

``stcvision calibrate --help`` lists the models, the patterns and the folds from here without
loading OpenCV or scipy; the modules that fit and detect import them from here too.
"""

from __future__ import annotations

__all__ = ["DEFAULT_FOLDS", "MODELS", "PATTERNS"]

#: the models and their parameters' names, in the order of the parameter vector
MODELS = {
    "mei": ("xi", "fu", "fv", "pu", "pv", "k1", "k2", "p1", "p2"),
    "poly": ("pu", "pv", "c", "e", "a0", "a2", "a3", "a4", "p1", "p2"),
}
#: the target patterns the image detector knows
PATTERNS = ("chessboard", "circles", "acircles")
#: folds of the held-out test (fewer when there are fewer views)
DEFAULT_FOLDS = 5
