"""The torch-free runtime: load a model package, encode garments once, deform frames in batches,
apply the effects a scene asks for, and stream the result to a writer.  Imports onnxruntime and
numpy -- never torch."""

from .deformer import Deformer
from .package import ModelPackage, PackageError
from .pipeline import Run, RunSummary, run_scene

__all__ = ["ModelPackage", "PackageError", "Deformer", "Run", "RunSummary", "run_scene"]
