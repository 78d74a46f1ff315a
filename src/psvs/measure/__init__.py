"""From matched pixels to millimetres: the paper's equations (9)-(17) and exact triangulation."""
