"""One soft disk compressed in a box (the paper's Eq. 2 and Fig. 5): see README.md."""
