"""The pipeline's messages in Foxglove's well-known schemas: the MCAP writer and the live
WebSocket bridge (``bridge``)."""
