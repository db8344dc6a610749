"""depthgram.sources."""
