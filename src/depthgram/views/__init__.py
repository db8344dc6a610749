"""depthgram.views."""
