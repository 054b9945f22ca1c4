"""The file tree a test puts into an object store and gets back: which local file is which
object's name under a prefix. Shared by s3_objects.py and azure_objects.py."""

import os


def names(local, prefix):
    """(path, name) of every file under `local`, each named `prefix/relative path`."""
    for d, _, files in os.walk(local):
        for f in files:
            path = os.path.join(d, f)
            yield path, f"{prefix}/{os.path.relpath(path, local)}".lstrip("/")


def destination(local, prefix, name):
    """Where the object `name` under `prefix` goes below `local` (its folder made)."""
    dest = os.path.join(local, os.path.relpath(name, prefix))
    os.makedirs(os.path.dirname(dest), exist_ok=True)
    return dest
