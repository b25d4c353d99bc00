"""One working template per component interface; copy one to start your own algorithm."""
