#!/usr/bin/python3
"""Writes the .vdb file test_hostile_apps needs beyond tests/cloud/make_vdb_fixtures.py's, with
OpenVDB's own Python bindings (Debian python3-openvdb). Usage: make_hostile_vdb.py OUTDIR

twins.vdb   two float grids both named "density" (OpenVDB reads grids by name, so the
            statistics of one would size the voxels of the other): (0,0,0) = 0.5 and
            (40,0,0) = 0.25.
"""
import os
import sys

import pyopenvdb as vdb


def density(at, value):
    g = vdb.FloatGrid(0.0)
    g.name = "density"
    g.getAccessor().setValueOn(at, value)
    return g


def main(out):
    os.makedirs(out, exist_ok=True)
    vdb.write(os.path.join(out, "twins.vdb"), grids=[density((0, 0, 0), 0.5), density((40, 0, 0), 0.25)])


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: make_hostile_vdb.py OUTDIR")
    main(sys.argv[1])
