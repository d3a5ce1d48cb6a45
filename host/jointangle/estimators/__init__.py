"""Joint-angle estimators. `registry.ESTIMATORS` maps each name to its implementation."""
