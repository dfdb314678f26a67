#!/usr/bin/env python3
"""Mirror an OBJ scene (x -> -x) keeping its windings, as a handedness conversion between modellers exports it:
every face ends up inside out. Used to check that `lambert`'s orientation repair turns such a model back
(docs/benchmarks.md, "models inside out").

    python3 scripts/mirror_obj.py IN.obj OUT.obj [--keep-emitters]

--keep-emitters reverses the faces whose material emits (MTL Ke > 0) back to their original side: a light hanging
just below a ceiling and facing it is a valid (cove) light that no repair can tell from a reversed one.
The MTL file is referred to by its absolute path, so OUT.obj can be written anywhere.
"""
import os
import sys


def main():
    args = [a for a in sys.argv[1:] if not a.startswith('--')]
    keep = '--keep-emitters' in sys.argv[1:]
    if len(args) != 2:
        sys.exit(__doc__)
    src, dst = args
    here = os.path.dirname(os.path.abspath(src))
    emitting, material, out = set(), None, []
    with open(src) as f:
        for line in f:
            line = line.rstrip('\n')
            t = line.split()
            if t and t[0] == 'mtllib':
                path = os.path.join(here, line.split(None, 1)[1])
                line = 'mtllib ' + path
                current = None
                with open(path) as m:
                    for entry in m:
                        e = entry.split()
                        if e and e[0] == 'newmtl':
                            current = e[1]
                        elif e and e[0] == 'Ke' and any(float(x) > 0 for x in e[1:4]):
                            emitting.add(current)
            elif t and t[0] == 'v':
                t[1] = repr(-float(t[1]))
                line = ' '.join(t)
            elif t and t[0] == 'usemtl':
                material = t[1]
            elif t and t[0] == 'f' and keep and material in emitting:
                line = 'f ' + ' '.join(reversed(t[1:]))
            out.append(line)
    with open(dst, 'w') as f:
        f.write('\n'.join(out) + '\n')


if __name__ == '__main__':
    main()
