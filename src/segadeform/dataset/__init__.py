"""Ground-truth datasets: garments x body shapes x motions through the cloth simulator (no torch)."""

from .config import DatasetConfig, load_dataset_config
from .make import make_dataset, sample_plan
from .quality import QualityReport, quality_check
from .store import Sample, list_samples, load_sample

__all__ = [
    "DatasetConfig",
    "load_dataset_config",
    "make_dataset",
    "sample_plan",
    "QualityReport",
    "quality_check",
    "Sample",
    "load_sample",
    "list_samples",
]
