"""Point the ros-jazzy-* wheels' CMake exports at this interpreter's include directories.

The wheels were built under /opt/python/cp3XX-cp3XX and their installed *.cmake files still
name that machine's Python and numpy include paths, so CMake refuses to configure any package
that depends on their Python type support. Idempotent: rewrites only what still points away.
"""

from __future__ import annotations

import re
import sys
import sysconfig
from pathlib import Path

import numpy

FOREIGN_NUMPY = re.compile(r"/opt/python/cp3\d+-cp3\d+/lib/python3\.\d+/site-packages/numpy/_core/include")
FOREIGN_PYTHON = re.compile(r"/opt/python/cp3\d+-cp3\d+/include/python3\.\d+")


def main() -> None:
    prefix = Path(sys.argv[1] if len(sys.argv) > 1 else sys.prefix)
    python_include, numpy_include = sysconfig.get_paths()["include"], numpy.get_include()
    fixed = 0
    for path in (prefix / "share").glob("*/cmake/*.cmake"):
        text = path.read_text()
        new = FOREIGN_PYTHON.sub(python_include, FOREIGN_NUMPY.sub(numpy_include, text))
        if new != text:
            path.write_text(new)
            fixed += 1
    print(f"fix_ros_wheel_cmake: {fixed} CMake files now use {python_include} and {numpy_include}")


if __name__ == "__main__":
    main()
