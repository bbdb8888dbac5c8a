"""The SEGA reference model in PyTorch (extra ``torch``).  Nothing in the core,
runtime or CLI imports this package at module level."""

from .config import ModelConfig
from .network import SEGANet, load_checkpoint, save_checkpoint
from .sega import SEGABlock, TauLinear, theorem2_bound

__all__ = ["ModelConfig", "SEGANet", "load_checkpoint", "save_checkpoint", "SEGABlock", "TauLinear", "theorem2_bound"]
