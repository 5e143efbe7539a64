"""What the views share: the colour of a track, which image box it is (``tracks``, pure), and a frame as JPEG (``images``)."""
