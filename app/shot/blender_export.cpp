#include "shot/blender_export.h"

#include "cloud/cloud.h"
#include "core/files.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <optional>
#include <system_error>
#include <vector>

namespace fulgur::app {

namespace {

nlohmann::json vec(const glm::dvec3& v) { return nlohmann::json::array({v.x, v.y, v.z}); }

}  // namespace

void write_blender_export(const std::filesystem::path& dir, const view::StormView& view,
                          const view::ViewOptions& options, std::span<const lightning::LitSegment> lit,
                          const BlenderExport& e) {
    FULGUR_ASSERT(e.width > 0 && e.height > 0 && e.light_spacing > 0.0, "an image size and a light spacing");
    std::error_code ec;
    if (std::filesystem::exists(dir, ec) && !std::filesystem::is_directory(dir, ec))
        throw core::Error(dir.string(), "--blender needs a directory; this is a file");
    std::filesystem::create_directories(dir, ec);
    if (ec) throw core::Error(dir.string(), "cannot create the directory: " + ec.message());

    const scene::Scene& s = view.scene();
    const render::Settings st = view.frame_settings(options);
    // The density Cycles renders is the one the march draws: with the billows, the detailed
    // density sampled on a grid fine enough for the finest of them (within kMaxExportVoxels);
    // with the detail turned off, the density before it; without detail the density grid itself.
    std::optional<core::Grid3<float>> detailed;
    const core::Grid3<float>* drawn = &view.density();
    if (s.cloud.detail && e.undetailed) {
        if (st.detail) {
            const int refine = cloud::detail_refinement(e.undetailed->geom, *s.cloud.detail, kMaxExportVoxels);
            drawn = &detailed.emplace(
                cloud::detailed_on_finer_grid(*e.undetailed, cloud::DetailNoise(*s.cloud.detail), refine));
        } else {
            drawn = e.undetailed;
        }
    }
    const core::Grid3<float>& density = *drawn;

    cloud::VdbOutputGrid d;
    d.name = "density";
    d.values = &density;
    d.fog_volume = true;
    d.text = {{"fulgur_quantity", "cloud density rho in [0, 1]"},
              {"fulgur_units", "1 (extinction sigma_t = fulgur_extinction * rho, 1/m)"}};
    d.numbers = {{"fulgur_extinction", s.medium.extinction}};
    const cloud::VdbOutputGrid grids[] = {d};
    cloud::save_vdb(dir / "density.vdb", grids,
                    {{"fulgur_scene", e.scene}, {"fulgur_length_unit", "m (world space; z up)"}});
    // The rain the frame draws, as its own medium on the density's grid: its extinction per
    // metre (so the medium's extinction factor is 1), its albedo and phase.
    const cloud::RainField* rain = st.rain ? view.rain() : nullptr;
    if (rain && !(rain->max_extinction > 0.0)) rain = nullptr;  // a cloud too thin to rain
    if (rain) {
        cloud::VdbOutputGrid r;
        r.name = "rain";
        r.values = &rain->extinction;
        r.fog_volume = true;
        r.text = {{"fulgur_quantity", "rain extinction sigma_t"}, {"fulgur_units", "1/m"}};
        const cloud::VdbOutputGrid rain_grids[] = {r};
        cloud::save_vdb(dir / "rain.vdb", rain_grids,
                        {{"fulgur_scene", e.scene}, {"fulgur_length_unit", "m (world space; z up)"}});
    } else {
        std::filesystem::remove(dir / "rain.vdb", ec);  // not this frame's: no stale file beside it
    }

    nlohmann::json j;
    j["format"] = "fulgur-blender-frame";
    j["version"] = 1;
    j["scene"] = e.scene;
    j["frame"] = e.frame;
    j["units"] = {{"length", "m"}, {"radiance", "W m^-2 sr^-1"}, {"intensity", "W sr^-1"}, {"irradiance", "W m^-2"}};
    j["image"] = {{"width", e.width}, {"height", e.height}};
    j["camera"] = {{"position", vec(e.camera.position)},
                   {"target", vec(e.camera.target)},
                   {"up", vec(e.camera.up)},
                   {"vertical_fov_deg", e.camera.vertical_fov_deg}};
    const core::GridGeometry& g = density.geom;
    j["medium"] = {{"file", "density.vdb"},
                   {"grid", "density"},
                   {"extinction", s.medium.extinction},
                   {"albedo", s.medium.albedo},
                   {"g", s.medium.g},
                   {"voxel_size", g.voxel_size},
                   {"origin", vec(g.origin)},
                   {"dims", {g.dims.x, g.dims.y, g.dims.z}}};
    if (rain) {
        const core::GridGeometry& rg = rain->extinction.geom;
        j["rain"] = {{"file", "rain.vdb"},
                     {"grid", "rain"},
                     {"extinction", 1.0},
                     {"albedo", rain->albedo},
                     {"g", rain->g},
                     {"voxel_size", rg.voxel_size},
                     {"origin", vec(rg.origin)},
                     {"dims", {rg.dims.x, rg.dims.y, rg.dims.z}},
                     {"max_extinction", rain->max_extinction},
                     {"top", rain->top}};
    } else {
        j["rain"] = nullptr;
    }
    j["flash_colour"] = vec(st.flash_colour);

    // The lit channel as isotropic points (the truth's line sources, sampled).
    std::vector<transport::PointSource> points;
    const bool flash = st.flash_light && st.cloud_lighting;
    if (flash) lightning::append_point_sources(lit, e.light_spacing, points);
    nlohmann::json lights = nlohmann::json::array();
    for (const transport::PointSource& p : points)
        if (p.intensity > 0.0) lights.push_back({{"position", vec(p.position)}, {"intensity", p.intensity}});
    j["lights"] = std::move(lights);
    j["light_spacing"] = e.light_spacing;
    // The channel the camera sees (the bolt pass's core): each stretch with its intensity per
    // metre, drawn as a cylinder of the core's radius. Its light in the cloud is the points above.
    if (st.bolt && !e.drawn_channel.empty()) {
        FULGUR_ASSERT(e.channel_radius > 0.0, "a drawn channel needs its radius");
        nlohmann::json segs = nlohmann::json::array();
        for (const lightning::LitSegment& c : e.drawn_channel)
            if (c.intensity > 0.0) segs.push_back({c.a.x, c.a.y, c.a.z, c.b.x, c.b.y, c.b.z, c.intensity});
        j["channel"] = {{"radius", e.channel_radius}, {"segments", std::move(segs)}};
    } else {
        j["channel"] = nullptr;
    }

    // The sun or moon and the sky where they light the cloud in this frame.
    const sky::StaticLight& sl = view.static_light();
    const bool statics = st.static_light && st.cloud_lighting;
    if (sl.sun && options.sun && statics && view.shown_sun()) {
        const scene::Sun& sun = *view.shown_sun();
        j["sun"] = {{"direction", vec(view.sun_solved_direction())},
                    {"irradiance_rgb", vec(sun.irradiance * sun.colour)},
                    {"name", sun.name}};
    } else {
        j["sun"] = nullptr;
    }
    if (st.sky || (sl.sky && options.sky && statics))
        j["sky"] = {{"zenith_rgb", vec(st.sky_zenith)},
                    {"horizon_rgb", vec(st.sky_horizon)},
                    {"lights_cloud", sl.sky && options.sky && statics},
                    {"visible", st.sky}};
    else
        j["sky"] = nullptr;
    // Fulgur's cloud is not lit by the ground (the sky light stops at the horizon), so the
    // ground is drawn but lights nothing in Blender either.
    if (st.ground) {
        using G = render::GroundLook;
        j["ground"] = {{"height", st.ground_height},
                       {"albedo", st.ground_albedo},
                       {"pattern",
                        {{"cell_m", G::cell_m},
                         {"seed", G::seed},
                         {"low", G::low},
                         {"span", G::span},
                         {"tint_rgb", {G::tint_rgb[0], G::tint_rgb[1], G::tint_rgb[2]}}}},
                       {"haze_m", G::haze_m},
                       {"lights_cloud", false}};
    } else
        j["ground"] = nullptr;
    core::write_file(dir / "frame.json", j.dump(1) + "\n");
}

}  // namespace fulgur::app
