"""Scenes and their geometry: objects in the world frame and their support tree, frames and poses, surface types,
walls, the category taxonomy, scene types, the native scene format."""
