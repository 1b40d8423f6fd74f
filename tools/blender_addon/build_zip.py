#!/usr/bin/env python3
"""Builds the installable zip of the fluidtex Blender add-on.

Usage: python3 tools/blender_addon/build_zip.py [OUT.zip]   (default: fluidtex_blender.zip)
Then in Blender: Edit > Preferences > Add-ons > Install... > OUT.zip, and
tick "Animation: fluidtex".

The zip holds the package folder `fluidtex_blender/` (what Blender's
installer expects), without caches.
"""

import os
import sys
import zipfile

HERE = os.path.dirname(os.path.abspath(__file__))
PACKAGE = "fluidtex_blender"


def main():
    out = os.path.abspath(sys.argv[1] if len(sys.argv) > 1 else f"{PACKAGE}.zip")
    src = os.path.join(HERE, PACKAGE)
    names = []
    with zipfile.ZipFile(out + ".tmp", "w", zipfile.ZIP_DEFLATED) as z:
        for root, dirs, files in os.walk(src):
            dirs[:] = sorted(d for d in dirs if d != "__pycache__")
            for f in sorted(files):
                if f.endswith((".pyc", ".pyo")):
                    continue
                path = os.path.join(root, f)
                arc = os.path.relpath(path, HERE)
                z.write(path, arc)
                names.append(arc)
    os.replace(out + ".tmp", out)
    print(f"{out}: {', '.join(names)}")


if __name__ == "__main__":
    main()
