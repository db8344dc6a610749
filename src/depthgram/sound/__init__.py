"""depthgram.sound."""
