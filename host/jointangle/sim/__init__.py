"""Rig simulator: mechanisms, motion profiles, sensor models and the named scenarios."""
