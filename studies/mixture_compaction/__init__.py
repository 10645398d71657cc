"""Compaction of rigid/soft disk mixtures (the paper's main study): see README.md."""
