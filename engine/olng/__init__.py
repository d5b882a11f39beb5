"""Seed 003: online motion reconstruction from four accelerometers (Tautges et al. 2011).

Public API: `KnowledgeBase` (+ `ClipArrays`, `SensorRig`, `Rig`), `OLNGReconstructor.push(acc_g) -> ReconstructedPose`,
`OnlineLazyNeighbourhoodGraph`, `path_weights`, `KernelEnergy`, configs in `engine.olng.config`.
"""
from engine.olng.config import EnergyConfig, KnowledgeBaseConfig, NeighbourhoodGraphConfig, OLNGConfig
from engine.olng.energy import FrameProblem, KernelEnergy, weighted_pca
from engine.olng.graph import OnlineLazyNeighbourhoodGraph, path_weights
from engine.olng.knowledge_base import ClipArrays, KnowledgeBase, SensorRig
from engine.olng.pose import Rig, fk_root_frame
from engine.olng.reconstructor import OLNGReconstructor, ReconstructedPose

__all__ = [
    "ClipArrays", "EnergyConfig", "FrameProblem", "KernelEnergy", "KnowledgeBase", "KnowledgeBaseConfig",
    "NeighbourhoodGraphConfig", "OLNGConfig", "OLNGReconstructor", "OnlineLazyNeighbourhoodGraph", "ReconstructedPose",
    "Rig", "SensorRig", "fk_root_frame", "path_weights", "weighted_pca",
]
