"""What the views share: a track's colour and which image box it is (``tracks``, pure), a
stream's rate and latency (``meters``, pure), and a frame as JPEG (``images``)."""
