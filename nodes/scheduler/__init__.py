"""The motion scheduler of the paper's Figure 2."""
