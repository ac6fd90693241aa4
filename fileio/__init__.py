"""ncbot fileio: the one way ncbot writes a file that readers or a crash must never see half-written.

The bottom package: it imports no other ncbot package, and every ncbot package may import it.
"""
from ncbot.fileio.atomic import TEMP_GLOB, atomic_path, atomic_write_bytes, atomic_write_text, fsync_folder, move_aside

__all__ = ["TEMP_GLOB", "atomic_path", "atomic_write_bytes", "atomic_write_text", "fsync_folder", "move_aside"]
