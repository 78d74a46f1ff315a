"""The browser UI (psvs serve): FastAPI app, plain JS and canvas."""
