"""The ant-like STC robot (Srour & Abboud, "Optimally Covering an Unknown Environment with Ant-like STC
algorithm"): its finite-state machine (:mod:`.fsm`), the one STC
geometry on the board (:mod:`.geometry`), the grid oracle (:mod:`.oracle`) and the closed loop as
parts: plant (:mod:`.plant`), perception (:mod:`.perception`, :mod:`.frames`), referee
(:mod:`.referee`), observers (:mod:`.observers`, :mod:`.recorder`) and the loop (:mod:`.loop`).

``from stcvision.controllers.stc import run_cover, CoverConfig, is_complete`` (imported on first use).
"""

__all__ = ["CoverConfig", "is_complete", "run_cover"]


def __getattr__(name):
    if name in __all__:
        from stcvision.controllers.stc import loop

        return getattr(loop, name)
    raise AttributeError(name)
