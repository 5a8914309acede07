// fulgur::core — the foundation every module builds on, one topic per header:
//
//  * error.h     Error / FULGUR_ASSERT: the two tiers of failure (bad data vs programmer misuse).
//  * grid.h      Grid3<T>: dense 3D voxel grids with physical geometry; the ray-box clip.
//  * rng.h       Rng: PCG32, deterministic per (seed, stream); seed mixing.
//  * numerics.h  compensated sums, relative L2.
//  * basis3.h    an orthonormal basis around a unit vector.
//  * sphere_points.h  directions of equal solid angle (a Fibonacci sphere).
//  * parallel.h  threads (OpenMP underneath), the background Worker, Stopwatch.
//  * format.h    numbers, durations and sizes for people.
//  * files.h     bounded reads, atomic writes, file locks, finiteness checks.
//  * nrrd.h      NRRD import/export of grids.
//  * image.h     PNG export, pseudo-colour.
//
// This umbrella includes them all; a file that needs one topic may include just that header.
#pragma once

#include "core/basis3.h"
#include "core/error.h"
#include "core/files.h"
#include "core/format.h"
#include "core/grid.h"
#include "core/image.h"
#include "core/nrrd.h"
#include "core/numerics.h"
#include "core/parallel.h"
#include "core/rng.h"
#include "core/sphere_points.h"
