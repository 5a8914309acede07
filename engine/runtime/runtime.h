// fulgur::runtime — per-frame reconstruction of the cloud's radiance from a baked scene
// (Dobashi et al. 2007, section 7).
//
//   strikes at time t (lightning::Storm) -> lit segments -> point sources -> splat -> e_l
//   -> H^(m) = sum_{l: e_l != 0} e_l B_l^(m)  (sparse, only the requested directions m)
//   -> inverse Haar -> S^(m) on the lighting grid (+ optional ambient) -> render upload.
//
// A frame with no active flash costs nothing (no accumulation, no transform). Only the
// directions the caller asks for are reconstructed (the renderer knows which the view
// needs: render::Renderer::needed_directions). Components: the bake may store the direct
// (single-scattering) and the multiple-scattering parts of each basis separately; the
// caller chooses which to sum (both linear, so both go into the same H, one transform).
//
// One concept per header: baked_bases.h, reconstructor.h, strike_solver.h, instant_strikes.h,
// near_field.h, strike_diffusion.h, frame_pipeline.h, references.h (direct solve, truth); this
// umbrella includes them all.
//
// THESE HEADERS ARE THE CONTRACT between the run-time module and the apps (demo, shot tool,
// benchmarks). Changing them is fine when the implementation needs it; keep it small,
// documented, and free of GL / window-system types.
#pragma once

#include "runtime/baked_bases.h"
#include "runtime/frame_pipeline.h"
#include "runtime/instant_strikes.h"
#include "runtime/near_field.h"
#include "runtime/reconstructor.h"
#include "runtime/references.h"
#include "runtime/strike_diffusion.h"
#include "runtime/strike_solver.h"
