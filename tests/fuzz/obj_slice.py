#!/usr/bin/env python3
"""Writes objects [first, first + count) of an OBJ file as a self-contained OBJ: only the vertices their
faces use, re-indexed (absolute, 1-based), vertex lines kept verbatim. For fuzz seeds (make_seeds.sh)."""
import sys


def main():
    src, first, count = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
    verts, objects, current = [], [], None
    with open(src, encoding="utf-8", errors="surrogateescape") as f:
        for line in f:
            if line.startswith("v "):
                verts.append(line)
            elif line.startswith("o ") or line.startswith("g "):
                current = [line, []]
                objects.append(current)
            elif line.startswith("f ") and current is not None:
                current[1].append(line.split()[1:])
    def index(tok):
        v = int(tok.split("/")[0])
        return v if v > 0 else len(verts) + 1 + v

    out = sys.stdout
    remap = {}  # source vertex -> output vertex, over the whole slice (OBJ indices are global)
    for head, faces in objects[first:first + count]:
        # The object's new vertices first, then the object and its faces.
        for face in faces:
            for tok in face:
                v = index(tok)
                if v not in remap:
                    remap[v] = len(remap) + 1
                    out.write(verts[v - 1])
        out.write(head)
        for face in faces:
            out.write("f " + " ".join(str(remap[index(t)]) for t in face) + "\n")


if __name__ == "__main__":
    main()
