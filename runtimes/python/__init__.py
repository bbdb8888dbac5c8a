"""The torch-free runtime: load a model package, encode garments once, deform frames in batches,
apply the effects a scene asks for, and stream the result to a writer.  Imports onnxruntime and
numpy -- never torch."""

from .package import ModelPackage, PackageError
from .deformer import Deformer
from .pipeline import RunSummary, run_scene, Run

__all__ = ["ModelPackage", "PackageError", "Deformer", "Run", "RunSummary", "run_scene"]
