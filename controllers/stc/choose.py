"""The controller a run names (``CoverConfig.fsm``, ``--fsm``): :func:`make_controller`."""

from __future__ import annotations

from stcvision.controllers.stc.controller import CONTROLLERS, Controller, HostC, PythonController
from stcvision.errors import BadInputError

__all__ = ["make_controller"]


def make_controller(name: str, *, mcu: str | None = None) -> Controller:
    """Make the controller a run names.

    Parameters
    ----------
    name : str
        The controller (:data:`~stcvision.controllers.stc.controller.CONTROLLERS`): "python",
        "c" or "firmware".
    mcu : str or None
        The firmware's chip (:data:`stcvision.controllers.stc.mcu.MCUS`; None: the default).

    Returns
    -------
    Controller
        The controller, to be closed when the run ends. An unknown name raises BadInputError.
    """
    if name == "python":
        return PythonController()
    if name == "c":
        return HostC()
    if name == "firmware":
        from stcvision.controllers.stc.mcu import FirmwareController

        return FirmwareController(mcu)
    raise BadInputError(f"unknown controller '{name}': one of {', '.join(CONTROLLERS)}")
