"""Jamming of rigid-disk packings: see README.md."""
