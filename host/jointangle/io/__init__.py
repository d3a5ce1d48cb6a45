"""File formats: one reader/writer pair per format."""
