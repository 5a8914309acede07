// The plan of every light a scene calls for, and why (sky.h).
#include "sky/sky.h"

#include <sstream>

namespace fulgur::sky {

namespace {

std::string angles(const glm::dvec3& direction) {
    double el = 0.0, az = 0.0;
    scene::sun_angles(direction, el, az);
    return "elevation " + core::format_number(el, 3) + " deg, azimuth " + core::format_number(az, 3) + " deg";
}

}  // namespace

ScenePlan plan_scene(const scene::Scene& s, const core::Grid3<float>& density, const bake::PlanOptions& options) {
    const std::string file = s.file_name();
    const scene::Effects& e = s.effects;
    const bool lightning = e.lightning, sun = e.sun && s.sun, sky = e.sky && s.sky;
    if (!lightning && !sun && !sky)
        throw core::Error(file + ": /effects",
                          "the scene asks for nothing that lights the cloud: no lightning, no sun "
                          "and no sky (declare one, or switch one on in \"effects\")");
    if (!e.single_scattering && !e.multiple_scattering)
        throw core::Error(file + ": /effects",
                          "single_scattering and multiple_scattering are both false: no light "
                          "reaches the cloud, nothing to simulate");
    ScenePlan p;
    p.settings = solve_settings(s, density);
    p.directions = static_direction_count(s, p.settings);
    auto& why = p.reasons;
    if (p.settings.toward) {
        const glm::dvec3& c = *p.settings.toward;
        why.push_back(
            "transport.static_light.directions \"camera\": the sun's, moon's and sky's S toward the camera at (" +
            core::format_number(c.x) + ", " + core::format_number(c.y) + ", " + core::format_number(c.z) +
            ") m from every voxel, one field (exact from there only; another camera position is another "
            "solve); lightning keeps its " +
            std::to_string(s.effective_directions()) + " output directions");
    } else if (s.medium.g == 0.0)
        why.push_back(
            "g = 0 (isotropic scattering): S does not depend on direction, 1 output direction for every "
            "solve instead of " +
            std::to_string(s.directions));
    else
        why.push_back("g = " + core::format_number(s.medium.g) + ": " + std::to_string(p.directions) +
                      " output directions for every solve");

    // Lightning: the virtual-light bake.
    if (lightning) {
        p.lightning = bake::make_plan(s, density, options);
        p.virtual_lights = p.lightning->lights.count();
        why.push_back("lightning: a virtual-light bake of " + std::to_string(p.virtual_lights) +
                      " lights (the bake plan below), its bases in the .fgb");
    } else {
        why.push_back("no lightning (effects.lightning = false): no virtual-light bake, no .fgb");
    }

    // How the sun and the sky are solved.
    const std::string lattice = " (" + s.transport.lb_collision + " collision, " + s.transport.lb_thick_voxels +
                                " thick voxels, tolerance " + core::format_number(s.transport.lb_tolerance) + ")";
    const std::string how =
        p.settings.method == Method::MonteCarlo
            ? "every order by " + std::to_string(p.settings.truth_paths) +
                  " Monte Carlo paths from the box's boundary through the full-resolution density "
                  "(transport.static_light.solver \"monte_carlo\": the truth's estimator, no lattice)"
        : !e.multiple_scattering
            ? std::string("exact single scattering only (effects.multiple_scattering = false: no lattice solve)")
        : p.settings.exact_orders == 2
            ? "exact single scattering + order 2 by " + std::to_string(p.settings.order2_paths) +
                  " Monte Carlo paths through the full-resolution density + lattice-Boltzmann for orders >= 3" + lattice
            : "exact single scattering + lattice-Boltzmann for orders >= 2" + lattice;
    // The static light's transport grid (its dims for the reasons; no full-density copy).
    const solve::Media grid = solve::make_media(s, density, p.settings.refine, false);
    if (e.multiple_scattering && (sun || sky))
        why.push_back(
            "static light on the lighting grid refined by " + std::to_string(p.settings.refine) +
            (s.transport.static_refine > 0
                 ? std::string(" (transport.static_light.refine)")
                 : " (a transport voxel at density 1 at most one optical depth: extinction x " +
                       core::format_number(density.geom.voxel_size * s.lighting_downsample) + " m = " +
                       core::format_number(s.medium.extinction * density.geom.voxel_size * s.lighting_downsample) +
                       " optical depths per lighting voxel)") +
            (p.settings.method == Method::MonteCarlo ? std::string(", every order by Monte Carlo")
             : p.settings.exact_orders == 2          ? std::string(", order 2 exact")
                                                     : std::string(", order 2 by the lattice")) +
            (p.settings.keep_transport_grid
                 ? std::string(", S kept on that grid (transport.static_light.grid \"transport\")")
                 : std::string(", S averaged onto the lighting grid")) +
            ": docs/sky.md measures the configurations against the static light's truth");
    const core::Int3 td = grid.transport.density.dims();
    // A Monte Carlo solve runs on no transport grid: it tallies where S is kept.
    const std::string transport_grid = "on the " + std::to_string(td.x) + " x " + std::to_string(td.y) + " x " +
                                       std::to_string(td.z) + " transport grid (" +
                                       core::format_number(grid.transport.density.geom.voxel_size, 6) + " m voxels)";
    const std::string where =
        p.settings.method == Method::MonteCarlo
            ? std::string("tallied on the ") + (p.settings.keep_transport_grid ? "transport" : "lighting") + " grid"
            : transport_grid;

    // The sun (or moon).
    if (sun) {
        p.sun = true;
        p.sun_solves = 1;
        const std::string name = s.sun->name.empty() ? std::string("the sun") : s.sun->name;
        why.push_back(name + " (" + angles(s.sun->direction) + "): one solve per direction, " + how + " " + where +
                      ", per unit irradiance (irradiance and colour need no new solve); the renderer draws its "
                      "single scattering at full resolution");
    } else if (s.sun) {
        why.push_back("a sun is declared but effects.sun = false: no sun solve, no sunlight");
    } else {
        why.push_back("no sun in the scene: no sun solve");
    }

    // The sky dome.
    if (sky) {
        p.sky = true;
        p.sky_uniform = s.sky->zenith() == s.sky->horizon();
        const bool mc = p.settings.sky_paths > 0;
        p.sky_single_solves = mc ? 0 : p.settings.sky_samples;
        p.sky_lattice_solves = e.multiple_scattering ? (p.sky_uniform ? 1 : 2) : 0;
        const bool two = e.multiple_scattering && p.settings.exact_orders == 2;
        if (p.settings.method == Method::MonteCarlo) {
            p.sky_single_solves = p.sky_lattice_solves = 0;
            why.push_back(std::string("sky dome (") + (p.sky_uniform ? "uniform" : "zenith-horizon gradient") +
                          "): every order by " + std::to_string(p.settings.truth_paths) + " Monte Carlo paths per " +
                          (p.sky_uniform ? "dome" : "gradient end") +
                          " from the whole dome through the full-resolution density (transport.static_light.solver "
                          "\"monte_carlo\"), S on the " +
                          (p.settings.keep_transport_grid ? "transport" : "lighting") +
                          " grid, per unit radiance; the background is the same sky");
        } else
            why.push_back(std::string("sky dome (") + (p.sky_uniform ? "uniform" : "zenith-horizon gradient") + "): " +
                          (mc ? "order 1" + std::string(two ? " and 2" : "") + " by Monte Carlo from the whole dome (" +
                                    std::to_string(p.settings.sky_paths) + " paths per " +
                                    (p.sky_uniform ? "dome" : "gradient end") + ", no directions to band the shadows), "
                              : std::to_string(p.sky_single_solves) + " directions' exact single scattering, " +
                                    (two ? "their order 2 by Monte Carlo (" + std::to_string(p.settings.order2_paths) +
                                               " paths shared), "
                                         : std::string())) +
                          std::to_string(p.sky_lattice_solves) + " lattice solve" +
                          (p.sky_lattice_solves == 1 ? "" : "s") + (p.sky_uniform ? "" : " (one per gradient end)") +
                          " " + where + ", per unit radiance; the background is the same sky");
    } else if (s.sky) {
        why.push_back("a sky is declared but effects.sky = false: it is the background only, no sky light");
    } else {
        why.push_back("no sky in the scene: no sky solve; the background is the default dark night sky");
    }

    // S kept on the transport grid: the solves' fields and the renderer's copy grow with its
    // cells (refine^3 the lighting grid's), so it is bounded before anything is solved.
    if (p.settings.keep_transport_grid && (p.sun || p.sky)) {
        const double cells = double(grid.transport.density.geom.cell_count()), dirs = double(p.directions);
        const int fields = (p.sun ? 2 : 0) + (p.sky ? (p.sky_uniform ? 2 : 4) : 0);  // single + multiple each
        // Host: the fields (float); the renderer: an RGB float texture per direction (padded to
        // 16 bytes a texel) and the resolved one.
        const double bytes = double(fields) * dirs * cells * 4.0 + (dirs + 1.0) * cells * 16.0;
        const double limit = scene::memory_limit(s);
        if (bytes > limit)
            throw core::Error(file + ": /transport/static_light/grid",
                              "\"transport\" keeps the static light's S " + transport_grid + ": about " +
                                  core::format_bytes(bytes) + " (" + std::to_string(fields) + " fields x " +
                                  std::to_string(p.directions) + " directions, and the renderer's copy), over the " +
                                  "limit of " + core::format_bytes(limit) +
                                  (s.limits.memory_bytes > 0.0 ? " (limits.memory_gib)" : " (3/4 of physical memory)") +
                                  "; use \"lighting\" or a smaller transport.static_light.refine");
        why.push_back("the static light's S kept " + transport_grid + ": about " + core::format_bytes(bytes) +
                      " with the renderer's copy (refine^3 the lighting grid's)");
    }

    // Run-time effects.
    if (!e.glow) why.push_back("effects.glow = false: no glow pass");
    if (!e.ground) why.push_back("effects.ground = false: no ground plane");
    return p;
}

std::string ScenePlan::to_text() const {
    std::ostringstream o;
    o << "scene plan\n";
    o << "  virtual-light bake  " << (lightning ? std::to_string(virtual_lights) + " lights" : std::string("none"))
      << "\n";
    o << "  sun solves          " << sun_solves << "\n";
    o << "  sky solves          " << sky_single_solves << " single scattering, " << sky_lattice_solves << " lattice\n";
    o << "  directions          " << directions << "\n";
    o << "  why:\n";
    for (const std::string& r : reasons) o << "    - " << r << "\n";
    if (lightning) o << lightning->to_text();
    return o.str();
}

}  // namespace fulgur::sky
