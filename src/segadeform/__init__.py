"""segadeform: SEGA garment deformation, ONNX export and a torch-free runtime.

The core package (this one, minus ``model``, ``physics`` and ``train``) needs
only numpy, scipy and meshio.  Conventions used everywhere:

* units are metres, the up axis is +Y (SMPL's convention);
* the batch axis, where there is one, comes first;
* vertex order and count are those of the garment file, exactly.
"""

__version__ = "0.1.0"

UP_AXIS = "y"
UNITS = "m"
