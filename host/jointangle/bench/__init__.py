"""Benchmarks behind `jointangle bench KIND` (DESIGN.md §4)."""
