"""The hybrid tracker: tree filtering's dictionary proposes, a continuous silhouette fit refines."""
