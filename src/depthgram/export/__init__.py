"""Results in the tools robotics engineers already use: MCAP for Foxglove (:mod:`depthgram.export.mcap_file`)."""
