"""Checks of the files a command reads, made before any work (issue 32).

A FIFO, a device (``/dev/zero``) or a socket named where a config, a track file, a sweep file
or a fit is expected would block the reader or feed it without end: :func:`not_a_file` names
what it is instead, and each reader refuses it in its own one-line error. A missing path or a
folder is left to the readers, which say so their own way.
"""

import os
import stat

_KINDS = ((stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
          (stat.S_ISSOCK, "a socket"))


def not_a_file(path) -> str | None:
    """What is wrong with reading ``path`` as a file: ``"is a FIFO (named pipe), not a regular
    file"`` and the like, or None for a regular file, a folder or a path that does not exist."""
    try:
        mode = os.stat(path).st_mode  # stat never opens, so never blocks on a FIFO
    except (OSError, ValueError):
        return None
    for is_kind, kind in _KINDS:
        if is_kind(mode):
            return f"is {kind}, not a regular file (allowed: a regular file)"
    return None
