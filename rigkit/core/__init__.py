"""The lowest layer of shared mechanisms: atomic files, strict YAML, progress, tables,
decoders' output, memory for image-sized arrays, threads, untrusted folders, where outputs go,
signals.

Nothing here knows about cameras, sessions or depth; everything above may use it.
"""
