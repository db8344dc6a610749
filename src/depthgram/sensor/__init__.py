"""depthgram.sensor."""
