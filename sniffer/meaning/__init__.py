"""Provides what a frame means: annotation, dissection on demand, problems, SunSpec, filters."""
