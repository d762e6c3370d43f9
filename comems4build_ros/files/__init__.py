"""The bottom layer: files the package writes (atomic, all or nothing) and reads."""
