"""Image processing for the correspondence algorithm: filters, binarisation, edges, pipelines.
Knows nothing about rigs."""
