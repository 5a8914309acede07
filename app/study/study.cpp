#include "study/study.h"

#include "bake/bake.h"
#include "common/cli.h"
#include "core/core.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>

namespace fulgur::study {

bool read_fields(const std::filesystem::path& file, std::uint64_t key, transport::MonteCarloResult::Noise& noise,
                 transport::SourceField& single, transport::SourceField& multiple) {
    std::ifstream in(file, std::ios::binary);
    if (!in) return false;
    std::uint64_t k = 0;
    in.read(reinterpret_cast<char*>(&k), sizeof k);
    in.read(reinterpret_cast<char*>(&noise), sizeof noise);
    for (transport::SourceField* f : {&single, &multiple})
        in.read(reinterpret_cast<char*>(f->data.data()), std::streamsize(f->data.size() * sizeof(float)));
    return in && k == key;
}

void write_fields(const std::filesystem::path& file, std::uint64_t key, const transport::MonteCarloResult::Noise& noise,
                  const transport::SourceField& single, const transport::SourceField& multiple) {
    std::ofstream out(file, std::ios::binary);
    out.write(reinterpret_cast<const char*>(&key), sizeof key);
    out.write(reinterpret_cast<const char*>(&noise), sizeof noise);
    for (const transport::SourceField* f : {&single, &multiple})
        out.write(reinterpret_cast<const char*>(f->data.data()), std::streamsize(f->data.size() * sizeof(float)));
    if (!out) throw core::Error(file.string(), "cannot write the reference cache");
}

std::vector<StrikeCase> strike_cases(bool quick) {
    if (quick) return {{"storm.json", "storm", 2}};
    return {{"storm.json", "storm", 5}, {"dusk-storm.json", "dusk-storm", 3}, {"vdb-cloud.json", "vdb-cloud", 3}};
}

StrikeScene strike_scene(const std::string& file) {
    const scene::Scene base = scene::load_scene(std::filesystem::path(FULGUR_SOURCE_DIR) / "content/scenes" / file);
    core::Grid3<float> density = scene::make_density(base);
    bake::bake_if_stale(base, density, bake::default_fgb_path(base));
    runtime::BakedBases bases = runtime::BakedBases::load(bake::default_fgb_path(base), bake::scene_key(base, density));
    scene::Scene s = base;
    s.lightning.schedule.strike_rate = 0.0;
    solve::Media media = solve::make_media(s, density);
    return {std::move(s), std::move(density), std::move(bases), std::move(media)};
}

StrikeFrame strike_frame(const Context& ctx, const StrikeScene& scene, const std::string& stem, std::uint64_t seed,
                         std::uint64_t truth_paths) {
    StrikeFrame f;
    f.probe = std::make_unique<runtime::FramePipeline>(scene.scene, scene.density, scene.bases, std::nullopt,
                                                       scene::quality_preset("paper"));
    f.strike = f.probe->strike_at(0.0, seed);
    f.time = f.probe->storm().strike(f.strike).profile.stroke_onset.at(0) + 0.002;
    f.frame = f.probe->build(f.time, {});
    runtime::TruthOptions to;
    to.paths = truth_paths;
    to.seed = seed;
    f.truth = cached_truth(
        scene.scene, scene.density, f.frame.segments, to,
        ctx.file("truth-" + stem + "-" + std::to_string(seed) + "-" + std::to_string(truth_paths) + ".bin"));
    return f;
}

// The truth of a frame, kept in the study's folder keyed by the scene, the strike and a
// checksum of the lit channel (a changed bolt or timing recomputes it).
runtime::Truth cached_truth(const scene::Scene& s, const core::Grid3<float>& density,
                            std::span<const lightning::LitSegment> lit, const runtime::TruthOptions& to,
                            const std::filesystem::path& file) {
    std::uint64_t sum = core::hash_seed(to.paths, to.seed);
    for (const lightning::LitSegment& g : lit)
        for (const double v : {g.a.x, g.a.y, g.a.z, g.b.x, g.b.y, g.b.z, g.intensity})
            sum = core::hash_seed(sum, std::uint64_t(std::llround(v * 1e3)));
    const std::vector<glm::dvec3> dirs = transport::output_directions(s.effective_directions());
    core::GridGeometry g = density.geom;
    const int f = s.lighting_downsample;
    g.voxel_size *= f;
    g.dims = {(g.dims.x + f - 1) / f, (g.dims.y + f - 1) / f, (g.dims.z + f - 1) / f};
    runtime::Truth t;
    t.single = t.multiple = transport::SourceField(g, dirs);
    if (read_fields(file, sum, t.noise, t.single, t.multiple)) return t;
    t = runtime::truth(s, density, lit, {}, to);
    write_fields(file, sum, t.noise, t.single, t.multiple);
    return t;
}

std::vector<double> side_view(const transport::LightingMedium& m, std::size_t toward_camera,
                              const std::function<double(std::size_t, std::size_t)>& S) {
    const core::GridGeometry& g = m.density.geom;
    std::vector<double> img(std::size_t(g.dims.x) * std::size_t(g.dims.z), 0.0);
    const double h = g.voxel_size;
    for (int k = 0; k < g.dims.z; ++k)
        for (int i = 0; i < g.dims.x; ++i) {
            double tau = 0.0, sum = 0.0;
            for (int j = 0; j < g.dims.y; ++j) {
                const std::size_t c = g.index(i, j, k);
                const double st = m.sigma_t(c);
                sum += std::exp(-(tau + 0.5 * st * h)) * st * h * S(toward_camera, c);
                tau += st * h;
            }
            img[std::size_t(i) + std::size_t(g.dims.x) * std::size_t(k)] = sum;
        }
    return img;
}

double cloud_error(std::span<const float> x, std::span<const float> ref, const std::vector<float>& rho) {
    core::RelativeL2 e;
    const std::size_t cells = rho.size();
    for (std::size_t i = 0; i < ref.size(); ++i)
        if (rho[i % cells] > 0.0f) e.add(x[i], ref[i]);
    return e.value();
}

std::array<std::vector<float>, 2> paper_parts(const runtime::BakedBases& bases, const runtime::Frame& frame,
                                              std::size_t size) {
    runtime::Reconstructor rec(bases);
    std::array<std::vector<float>, 2> out;
    for (const bool single : {true, false}) {
        runtime::ReconstructOptions o;
        o.components = {single, !single};
        runtime::RadianceField r;
        runtime::StageTimes st;
        out[single ? 0 : 1] = rec.reconstruct(frame.weights, {}, o, r, st) ? flat(r) : std::vector<float>(size, 0.0f);
    }
    return out;
}

std::vector<float> flat(const runtime::RadianceField& r) {
    std::vector<float> v;
    for (const auto& d : r.values) v.insert(v.end(), d.begin(), d.end());
    return v;
}

std::size_t toward_side_camera(std::span<const glm::dvec3> dirs) {
    std::size_t best = 0;
    for (std::size_t m = 0; m < dirs.size(); ++m)
        if (dirs[m].y * -1.0 > dirs[best].y * -1.0) best = m;  // largest component along -y
    return best;
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

void Context::summary(const std::string& name, nlohmann::json j) const {
    if (!j.contains("study")) j["study"] = name;
    std::cout << j.dump() << std::endl;
}

std::filesystem::path Context::file(const std::string& name) const {
    std::error_code ec;
    std::filesystem::create_directories(output_dir, ec);
    if (ec) throw core::Error(output_dir.string(), "cannot create the output directory: " + ec.message());
    return output_dir / name;
}

Csv::Csv(const std::filesystem::path& path, const std::vector<std::string>& header)
    : path_(path), columns_(header.size()) {
    for (std::size_t i = 0; i < header.size(); ++i) buffer_ += (i ? "," : "") + header[i];
    buffer_ += "\n";
}
Csv& Csv::operator<<(double v) {
    buffer_ += (first_in_row_ ? "" : ",") + core::format_number(v, 9);
    first_in_row_ = false;
    ++in_row_;
    return *this;
}
Csv& Csv::operator<<(const std::string& v) {
    // RFC 4180: a field holding a comma, a quote or a line break is quoted, quotes doubled.
    std::string field = v;
    if (field.find_first_of(",\"\n\r") != std::string::npos) {
        field = "\"";
        for (const char c : v) field += c == '"' ? std::string("\"\"") : std::string(1, c);
        field += "\"";
    }
    buffer_ += (first_in_row_ ? "" : ",") + field;
    first_in_row_ = false;
    ++in_row_;
    return *this;
}
void Csv::end_row() {
    FULGUR_ASSERT(in_row_ == columns_, "CSV row has the wrong number of columns");
    buffer_ += "\n";
    first_in_row_ = true;
    in_row_ = 0;
}
void Csv::flush() { core::write_file(path_, buffer_); }
Csv::~Csv() {
    try {
        flush();
    } catch (const std::exception& e) {
        std::fprintf(stderr, "fulgur-study: %s\n", e.what());
    }
}

}  // namespace fulgur::study

int main(int argc, char** argv) {
    fulgur::study::Context ctx;
    return fulgur::app::registry_main(argc, argv,
                                      {"fulgur-study", "study",
                                       "Runs the named studies (all if none), writing CSV files into DIR (drawn by\n"
                                       "scripts/plot_studies.py)\n"
                                       "(default ./study-output) and one JSON summary line per study on stdout.",
                                       16},
                                      ctx, [&ctx](CLI::App& app) {
                                          app.add_option("-o,--output", ctx.output_dir,
                                                         "output directory (default ./study-output)")
                                              ->type_name("DIR");
                                          app.add_option("--only", ctx.only,
                                                         "run only the named configurations, comma-separated; "
                                                         "\"P*\" names every one starting with P (frontier)")
                                              ->type_name("NAMES");
                                      });
}
