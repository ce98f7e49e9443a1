"""What people read: the comparisons' summary and tables, the report plots
(matplotlib), the preview images with their targets, and the rig check as text."""
