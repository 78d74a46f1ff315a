"""Render PSVS complex images of 3-D scenes through the exact optics, with a realistic sensor."""
