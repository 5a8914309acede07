// fulgur-bake: scene -> plan -> baked virtual-light bases (.fgb), report and NRRD export; the
// sun's and the sky's solves into their cache files. Thin: the work is engine/bake (bake.h)
// and engine/sky (sky.h); this file parses arguments and prints.
#include "bake/bake.h"
#include "common/bake_args.h"
#include "common/lighting_vdb.h"
#include "common/progress.h"
#include "common/tool_start.h"
#include "core/core.h"
#include "distributed/distributed.h"
#include "scene/scene.h"
#include "sky/sky.h"

#include <nlohmann/json.hpp>

#include <csignal>
#include <cstdio>
#include <exception>
#include <functional>
#include <map>
#include <vector>

using namespace fulgur;

namespace {

nlohmann::json report_json(const bake::Plan& plan, const bake::Report& r, const std::filesystem::path& out, int ranks) {
    nlohmann::json j;
    j["file"] = out.string();
    j["ranks"] = ranks;
    j["lighting_grid"] = {plan.lighting.dims.x, plan.lighting.dims.y, plan.lighting.dims.z};
    j["virtual_lights"] = {plan.lights.x.size(), plan.lights.y.size(), plan.lights.z.size()};
    j["directions"] = plan.directions;
    j["components"] = plan.components;
    j["solver"] = plan.solver;
    j["threads"] = r.threads;
    j["seconds"] = {{"total_wall", r.seconds_total},
                    {"single_cpu", r.seconds_single},
                    {"multiple_cpu", r.seconds_multiple},
                    {"compress_cpu", r.seconds_compress},
                    {"write", r.seconds_write}};
    j["lights"] = r.lights;
    j["lights_dropped"] = r.lights_dropped;
    j["lights_resumed"] = r.lights_resumed;
    j["max_dropped_fraction"] = r.max_dropped_fraction;
    j["raw_bytes"] = r.raw_bytes;
    j["file_bytes"] = r.file_bytes;
    j["coefficients_kept"] = r.coefficients_kept;
    j["compression_ratio"] = r.compression_ratio;
    j["relative_l2_error"] = r.relative_l2_error;
    j["solver_iterations"] = {{"mean", r.mean_solver_iterations}, {"max", r.max_solver_iterations}};
    j["unconverged_lights"] = r.unconverged;
    j["expected"] = {{"seconds", plan.expected_seconds}, {"bytes", plan.expected_bytes}};
    return j;
}

// --export's lights, checked against the plan.
std::vector<basis::WeightedLight> export_lights(const app::BakeArgs& a, const bake::Plan& plan) {
    std::vector<basis::WeightedLight> lights;
    for (const app::ExportLight& e : a.export_lights) {
        if (e.light >= plan.lights.count())
            throw core::Error("", "--export: light " + std::to_string(e.light) + " is out of range (the bake has " +
                                      std::to_string(plan.lights.count()) + " lights)");
        lights.push_back({e.light, e.weight});
    }
    return lights;
}

// --vdb: the density and --export's sum from the .fgb, every direction, as PREFIX.vdb.
void export_vdb(const app::BakeArgs& a, const scene::Scene& s, const core::Grid3<float>& density,
                const bake::Plan& plan, const std::filesystem::path& fgb) {
    const std::vector<basis::WeightedLight> lights = export_lights(a, plan);
    const basis::BakedBasis baked = basis::load_fgb(fgb);
    app::LightingVdb v;
    v.scene = s.name + " (" + a.scene.string() + ")";
    v.extinction = s.medium.extinction;
    v.density = &density;
    std::string list;
    for (const basis::WeightedLight& w : lights)
        list += (list.empty() ? "" : ", ") + std::to_string(w.light) + ":" + core::format_number(w.weight, 6);
    v.source_meaning = "sum of virtual lights (index:weight) " + list + " of " + fgb.filename().string() +
                       ", each of unit radiant intensity (1 W/sr), reconstructed from the compressed bases";
    for (std::size_t m = 0; m < plan.output_directions.size(); ++m) {
        v.source.push_back(basis::reconstruct(baked, lights, m));
        v.directions.push_back(plan.output_directions[m]);
    }
    const std::filesystem::path out = a.vdb_prefix.string() + ".vdb";
    app::write_lighting_vdb(out, v);
    std::printf("exported %s (density and S in %zu directions)\n", out.string().c_str(), v.source.size());
}

void export_nrrd(const app::BakeArgs& a, const scene::Scene& s, const core::Grid3<float>& density,
                 const bake::Plan& plan, const std::filesystem::path& fgb) {
    const std::size_t nd = plan.output_directions.size();
    if (std::size_t(a.export_direction) >= nd)
        throw core::Error("", "--direction " + std::to_string(a.export_direction) + " is out of range (the bake has " +
                                  std::to_string(nd) + " directions)");
    const std::vector<basis::WeightedLight> lights = export_lights(a, plan);
    const basis::BakedBasis baked = basis::load_fgb(fgb);
    const std::filesystem::path comp = a.export_prefix.string() + "_compressed.nrrd";
    basis::export_compressed_nrrd(comp, baked, lights, std::size_t(a.export_direction));
    // Raw: solve the listed lights again; the stored components are summed, as in the
    // compressed export.
    const solve::Media media = solve::make_media(s, density);
    std::map<std::uint32_t, transport::SourceField> fields;
    for (const basis::WeightedLight& w : lights) {
        if (fields.count(w.light)) continue;
        transport::SourceField f = bake::solve_light(s, media, plan, w.light);
        if (plan.components == 2) {
            const std::size_t cells = f.cells();
            for (std::size_t i = 0; i < nd * cells; ++i) f.data[i] += f.data[nd * cells + i];
            f.data.resize(nd * cells);
            f.directions.resize(nd);
        }
        fields.emplace(w.light, std::move(f));
    }
    const std::filesystem::path raw = a.export_prefix.string() + "_raw.nrrd";
    basis::export_raw_nrrd(raw, lights, std::size_t(a.export_direction),
                           [&](std::uint32_t l) -> const transport::SourceField& { return fields.at(l); });
    std::printf("exported %s and %s\n", raw.string().c_str(), comp.string().c_str());
}

// Every file the bake writes is new or its own, never an input or another output.
void check_outputs(const app::BakeArgs& a, const scene::Scene& s, const std::filesystem::path& out) {
    std::vector<core::NamedPath> inputs{{"scene", a.scene}};
    if (s.cloud.kind != scene::CloudSource::Kind::Generator) inputs.push_back({"cloud file", s.cloud.file});
    std::vector<core::NamedPath> outputs{{"baked file", out}};
    if (a.report) outputs.push_back({"report", *a.report});
    if (!a.export_lights.empty() && !a.export_prefix.empty()) {
        outputs.push_back({"raw export", a.export_prefix.string() + "_raw.nrrd"});
        outputs.push_back({"compressed export", a.export_prefix.string() + "_compressed.nrrd"});
    }
    if (!a.vdb_prefix.empty()) outputs.push_back({"VDB export", a.vdb_prefix.string() + ".vdb"});
    core::check_distinct_files(inputs, outputs);
}

// The sun's and the sky's solves (the plan's static light), cached: over every rank of the
// session (rank 0 reads and writes the cache files and prints; every rank takes part in a
// solve, with the same result as one process).
void solve_static_light(const distributed::Session& session, const scene::Scene& s, const core::Grid3<float>& density,
                        sky::ScenePlan plan) {
    plan.settings = distributed::static_light_settings(session, plan.settings);
    std::function<void(const std::string&)> say;
    if (session.rank() == 0) say = [](const std::string& m) { std::printf("%s\n", m.c_str()); };
    (void)sky::load_or_solve(s, density, sky::static_media(s, density), plan, {}, say);
}

// A rank other than 0 of a distributed run: waits for rank 0's decisions, takes part in the
// sun's and the sky's solves, then solves the chunks of the bake it is handed (rank 0 prints
// and writes every file).
int help_bake(const distributed::Session& session, const scene::Scene& s, const core::Grid3<float>& density) {
    bake::PlanOptions po;
    po.estimate = false;
    if (session.broadcast(0)) solve_static_light(session, s, density, sky::plan_scene(s, density, po));
    if (!session.broadcast(0)) return 0;
    (void)distributed::bake(session, s, density, bake::make_plan(s, density, po), {});
    return 0;
}

// Rank 0 tells the other ranks, once each and in this order on every path, whether the sun
// and the sky are solved (they take part) and whether it bakes.
struct Decision {
    const distributed::Session& session;
    bool told_static = false, told_bake = false;
    void tell_static(bool solve) {
        if (!told_static) (void)session.broadcast(solve ? 1 : 0);
        told_static = true;
    }
    void tell(bool bake) {
        tell_static(false);
        if (!told_bake) (void)session.broadcast(bake ? 1 : 0);
        told_bake = true;
    }
    ~Decision() {
        if (std::uncaught_exceptions() == 0) tell(false);
    }
};

bake::BakeOptions bake_options(const app::BakeArgs& a, const std::filesystem::path& out) {
    bake::BakeOptions o;
    if (!a.checkpoint) return o;
    o.checkpoint = bake::checkpoint_path(out);
    std::error_code ec;
    if (a.fresh) {
        std::filesystem::remove_all(o.checkpoint, ec);
        if (ec) throw core::Error(o.checkpoint.string(), "--fresh: cannot remove the checkpoint: " + ec.message());
    } else if (std::filesystem::exists(o.checkpoint, ec)) {
        // Said before the checks: the bake reports how many lights it took once they passed.
        std::printf("found the checkpoint %s: the lights that pass its checks are reused (--fresh discards it)\n",
                    o.checkpoint.string().c_str());
    }
    if (a.stop_after)
        o.on_checkpoint = [n = a.stop_after](std::size_t lights) {
            if (lights < n) return;
            std::fflush(stdout);
            std::fflush(stderr);
            std::raise(SIGKILL);  // as a lost node or a time limit would: no clean-up at all
        };
    return o;
}

int run(const app::BakeArgs& a, const distributed::Session& session) {
    if (a.threads > 0) core::set_thread_count(a.threads);
    const scene::Scene s = scene::load_scene(a.scene);
    const std::filesystem::path out = a.output ? *a.output : bake::default_fgb_path(s);
    check_outputs(a, s, out);
    const core::Grid3<float> density = scene::make_density(s);
    if (session.rank() != 0) return help_bake(session, s, density);
    Decision decision{session};

    std::string why;
    const bool fresh = s.effects.lightning && bake::up_to_date(s, density, out, &why);
    bake::PlanOptions po;
    po.estimate = !fresh || a.force || a.dry_run;
    po.on_progress = [](const std::string& line) {
        std::fprintf(stderr, "fulgur-bake: %s\n", line.c_str());
        std::fflush(stderr);
    };
    const sky::ScenePlan scene_plan = sky::plan_scene(s, density, po);
    std::fputs(scene_plan.to_text().c_str(), stdout);
    if (scene_plan.lightning)
        std::printf("  output          %s (%s)\n", out.string().c_str(), fresh ? "up to date" : why.c_str());
    std::fflush(stdout);
    if (a.dry_run) return 0;
    decision.tell_static(scene_plan.sun || scene_plan.sky);
    if (scene_plan.sun || scene_plan.sky) {
        if (session.distributed()) std::printf("the static light's solves over %d ranks\n", session.size());
        std::fflush(stdout);
        solve_static_light(session, s, density, scene_plan);
    }
    if (!scene_plan.lightning) {
        if (!a.export_lights.empty())
            throw core::Error(a.scene.string(), "--export: the scene has no lightning to bake");
        std::printf("no virtual-light bake: the scene has no lightning\n");
        return 0;
    }
    const bake::Plan& plan = *scene_plan.lightning;

    if (fresh && !a.force) {
        decision.tell(false);
        std::printf("%s is up to date; nothing to bake (--force rebakes)\n", out.string().c_str());
    } else {
        decision.tell(true);
        const bake::BakeOptions options = bake_options(a, out);
        if (session.distributed())
            std::printf("distributed over %d ranks, %d thread(s) on rank 0\n", session.size(), plan.threads);
        std::fflush(stdout);
        const bake::Report r =
            *distributed::bake(session, s, density, plan, out, options, app::make_progress_printer(stderr, "lights"));
        if (r.lights_resumed) std::printf("%zu lights came from the checkpoint\n", r.lights_resumed);
        std::printf(
            "baked %s in %s: %zu lights (%zu dropped), %.1f MB raw -> %.2f MB file (1/%.0f), "
            "%llu coefficients, relative L2 error %.3g%%, solver iterations mean %.0f max %.0f%s\n",
            out.string().c_str(), core::format_seconds(r.seconds_total).c_str(), r.lights, r.lights_dropped,
            double(r.raw_bytes) / 1e6, double(r.file_bytes) / 1e6, r.compression_ratio,
            static_cast<unsigned long long>(r.coefficients_kept), 100.0 * r.relative_l2_error, r.mean_solver_iterations,
            r.max_solver_iterations,
            r.unconverged ? (", " + std::to_string(r.unconverged) + " lights hit the iteration cap").c_str() : "");
        if (a.report) core::write_file(*a.report, report_json(plan, r, out, session.size()).dump(2) + "\n");
    }
    if (!a.export_lights.empty() && !a.export_prefix.empty()) export_nrrd(a, s, density, plan, out);
    if (!a.vdb_prefix.empty()) export_vdb(a, s, density, plan, out);
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    // First: under mpirun or srun this joins the other ranks (a plain run never touches MPI).
    const distributed::Session session(argc, argv);
    app::BakeArgs a;
    if (const std::optional<int> status = app::start(argc, argv, a, app::parse_bake_args, app::bake_usage))
        return *status;
    try {
        return run(a, session);
    } catch (const std::exception& e) {
        if (!session.distributed()) {
            std::fprintf(stderr, "fulgur-bake: %s\n", e.what());
            return app::kExitFailure;
        }
        // One rank's failure ends the run: the others may be waiting for it.
        std::fprintf(stderr, "fulgur-bake (rank %d of %d): %s\n", session.rank(), session.size(), e.what());
        session.abort(app::kExitFailure);
    }
}
