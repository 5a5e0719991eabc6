"""Writers turn finished strokes into files. They compute no geometry."""
