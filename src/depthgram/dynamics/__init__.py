"""depthgram.dynamics."""
