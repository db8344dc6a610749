"""depthgram.act."""
