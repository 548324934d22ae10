"""Figures (Matplotlib, drawn off-screen)."""
