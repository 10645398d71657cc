"""Stage 1 of the toolkit: disk meshes (gmsh), packings, materials and laws; writes scene folders."""
