"""Pure appearance-descriptor code: numpy/cv2/onnxruntime only, no messages, no I/O besides model files."""

from services.embedder.core.backend import Backend, Card, EmbedderError, crop_boxes
from services.embedder.core.colour import ColourDescriptor

__all__ = ["Backend", "Card", "ColourDescriptor", "EmbedderError", "crop_boxes"]
