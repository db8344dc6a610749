"""depthgram."""
