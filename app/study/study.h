// fulgur-study: accuracy/time studies that write CSV tables (scripts/plot_studies.py draws them).
//
// Each study file registers itself with FULGUR_STUDY(name, "help") { ... } and writes its
// results into ctx.output_dir (CSV, and a one-line JSON summary on stdout; scripts/plot_studies.py draws the figures). Studies
// are the "accuracy costs time" evidence (docs/design.md#accuracy-costs-time): every knob measured against a
// reference. They may take minutes; --quick runs a reduced version for smoke tests.
#pragma once

#include "common/registry.h"
#include "runtime/baked_bases.h"
#include "runtime/frame_pipeline.h"
#include "runtime/reconstructor.h"
#include "runtime/references.h"
#include "scene/scene.h"
#include "solve/solve.h"
#include "transport/transport.h"

#include <nlohmann/json.hpp>

#include <array>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace fulgur::study {

struct Context {
    std::filesystem::path output_dir = "study-output";
    bool quick = false;
    /// --only A,B,P*: studies with configurations run only those named (P*: names starting with P).
    std::string only;
    /// Prints one JSON object on one line (adds "study" if missing) and flushes.
    void summary(const std::string& name, nlohmann::json j) const;
    /// output_dir / file, creating output_dir.
    std::filesystem::path file(const std::string& name) const;
};

/// FULGUR_STUDY(lb_convergence, "lb-convergence", "help") { ... uses ctx ... }
#define FULGUR_STUDY(ident, name, help) FULGUR_REGISTRY_ENTRY(::fulgur::study::Context, ident, name, help)

/// A small CSV writer: header once, then rows of numbers or strings; throws core::Error
/// naming the file if it cannot be written.
class Csv {
public:
    Csv(const std::filesystem::path& path, const std::vector<std::string>& header);
    Csv& operator<<(double v);
    Csv& operator<<(const std::string& v);
    void end_row();

private:
    std::filesystem::path path_;
    std::string buffer_;
    bool first_in_row_ = true;
    std::size_t columns_ = 0, in_row_ = 0;
    void flush();

public:
    ~Csv();
};

/// The lattice against the truth for lights in the storm's core, at its edge and below its
/// base, today's lattice and the refined one (part of lb-vs-mc; study_lb_truth.cpp).
void lb_vs_truth(const Context& ctx);

/// A reference's single and multiple fields and their noise kept in `file` under `key`
/// (binary: key, noise, the fields' floats). read_fields fills the fields (sized by the caller)
/// and returns true when the file holds that key; write_fields throws core::Error naming the
/// file when it cannot be written.
bool read_fields(const std::filesystem::path& file, std::uint64_t key, transport::MonteCarloResult::Noise& noise,
                 transport::SourceField& single, transport::SourceField& multiple);
void write_fields(const std::filesystem::path& file, std::uint64_t key, const transport::MonteCarloResult::Noise& noise,
                  const transport::SourceField& single, const transport::SourceField& multiple);

/// The truth of a frame (runtime::truth), kept in `file` keyed by the options and a checksum of
/// the lit channel (a changed bolt or timing recomputes it).
runtime::Truth cached_truth(const scene::Scene& s, const core::Grid3<float>& density,
                            std::span<const lightning::LitSegment> lit, const runtime::TruthOptions& to,
                            const std::filesystem::path& file);

/// A content scene (`content/scenes/<file>`) made ready for studies of its strikes: the scene
/// with no strikes of its own schedule (only the study's), its density, its bases (baked first
/// when missing or stale) and its media.
struct StrikeScene {
    scene::Scene scene;
    core::Grid3<float> density;
    runtime::BakedBases bases;
    solve::Media media;
};
StrikeScene strike_scene(const std::string& file);

/// The scenes the strike studies measure and how many strikes each: the default storm's 5,
/// dusk-storm's and vdb-cloud's 3 (quick: the storm's first 2).
struct StrikeCase {
    std::string file, stem;
    int strikes = 0;
};
std::vector<StrikeCase> strike_cases(bool quick);

/// Strike `seed` alone in a StrikeScene at its first return stroke + 2 ms: the paper preset's
/// frame of it and that frame's truth (cached_truth in ctx's folder, as
/// truth-<stem>-<seed>-<truth_paths>.bin; seed `seed`).
struct StrikeFrame {
    std::unique_ptr<runtime::FramePipeline> probe;  ///< built the frame; its storm holds the strike
    std::size_t strike = 0;                         ///< the strike's index in probe->storm()
    double time = 0.0;                              ///< the frame's storm time, s
    runtime::Frame frame;
    runtime::Truth truth;
};
StrikeFrame strike_frame(const Context& ctx, const StrikeScene& scene, const std::string& stem, std::uint64_t seed,
                         std::uint64_t truth_paths);

/// A side view on the lighting grid, the quantity an image integrates: a camera far along -y
/// looking along +y sees per (x, z) column sum_j T_j sigma_t,j S_j(toward the camera) h with
/// T_j the transmittance from the camera to voxel j (voxel midpoint). The paper compared
/// images; this is that comparison without the renderer's resampling. S(m, cell).
std::vector<double> side_view(const transport::LightingMedium& m, std::size_t toward_camera,
                              const std::function<double(std::size_t, std::size_t)>& S);
/// Relative L2 of x against ref over the cloud voxels (lighting-grid density `rho` > 0), every
/// direction (direction-major fields).
double cloud_error(std::span<const float> x, std::span<const float> ref, const std::vector<float>& rho);

/// The paper frame's single and multiple parts apart ([0], [1]; direction-major, every
/// direction), reconstructed from `frame`'s light weights; zeros of `size` when no light is lit.
std::array<std::vector<float>, 2> paper_parts(const runtime::BakedBases& bases, const runtime::Frame& frame,
                                              std::size_t size);

/// A frame's radiance for all its directions as one direction-major array.
std::vector<float> flat(const runtime::RadianceField& r);

/// The index of the direction in `dirs` closest to -y (toward side_view's camera).
std::size_t toward_side_camera(std::span<const glm::dvec3> dirs);

/// Wall seconds from `t0` to now (the studies' cost columns).
double seconds_since(std::chrono::steady_clock::time_point t0);

}  // namespace fulgur::study
