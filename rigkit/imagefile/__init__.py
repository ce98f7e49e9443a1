"""Image files: camera RAW through LibRaw (:mod:`~rigkit.imagefile.rawio`), the size in
a file's header before it is decoded (:mod:`~rigkit.imagefile.imagesize`), ordinary
images decoded by OpenCV (:mod:`~rigkit.imagefile.decode`), whether a decoded frame holds
a picture (:mod:`~rigkit.imagefile.picture`) and the EXIF fields rigkit checks
(:mod:`~rigkit.imagefile.exif`). Below the pipeline, which takes arrays and knows
nothing of files; above :mod:`rigkit.core`."""
