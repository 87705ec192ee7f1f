"""A click answered: the query and what the engine reads from it, the paper's scoring and placement, heading scores,
the fit checks."""
