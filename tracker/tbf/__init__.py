"""Paper 2: silhouette tree-based filtering (distances, pose sample sets, the tree, motion models, the filter)."""
