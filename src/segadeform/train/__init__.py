"""Training and evaluation of the SEGA model on simulated ground truth (needs torch).

Nothing in the runtime or CLI core imports this package at module level.
"""

from .config import LossWeights, TrainConfig, load_train_config

__all__ = ["TrainConfig", "LossWeights", "load_train_config"]
