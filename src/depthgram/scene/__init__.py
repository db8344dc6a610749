"""depthgram.scene."""
