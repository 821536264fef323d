"""workbench: identify and propagate the variability of bolted joints in light assembled frames.

The method is that of Ghienne, Laurent & Blanze, "Robust characterization of the vibrational
behaviour of light assembled structures with random parameters", MSSP 136 (2020) 106510.
"""

from workbench.io.outputs import write_frame
from workbench.model.assembly import Model, assemble
from workbench.model.frame import Frame, FrameFileError
from workbench.model.frame_file import read_frame
from workbench.model.modal import FRFSet, Modes, mac, model_modes, solve_modes
from workbench.model.structure import structure_frf

__all__ = [
    "Frame",
    "FrameFileError",
    "read_frame",
    "write_frame",
    "Model",
    "assemble",
    "Modes",
    "FRFSet",
    "solve_modes",
    "model_modes",
    "mac",
    "structure_frf",
]
__version__ = "0.1.0"
