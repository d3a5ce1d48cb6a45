"""The neighbouring methods of ../shared/seeds/ as host estimators (issue 8)."""
