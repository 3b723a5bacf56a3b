"""Provides modscope's benchmarks: speed and memory against independent peers."""
