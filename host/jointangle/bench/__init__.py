"""Benchmarks behind `jointangle bench KIND` (docs/design.md §4)."""
