"""depthgram.segment."""
