#include "lighting_vdb.h"

#include "cloud/cloud.h"

#include <cstdio>

namespace fulgur::app {

void write_lighting_vdb(const std::filesystem::path& path, const LightingVdb& v) {
    FULGUR_ASSERT(v.density && v.source.size() == v.directions.size(), "one S grid per direction, and a density");
    std::vector<cloud::VdbOutputGrid> grids;
    cloud::VdbOutputGrid d;
    d.name = "density";
    d.values = v.density;
    d.fog_volume = true;
    d.text = {{"fulgur_quantity", "cloud density rho in [0, 1]"},
              {"fulgur_units", "1 (extinction sigma_t = fulgur_extinction * rho, 1/m)"}};
    d.numbers = {{"fulgur_extinction", v.extinction}};
    grids.push_back(d);
    for (std::size_t m = 0; m < v.source.size(); ++m) {
        char name[32];
        std::snprintf(name, sizeof name, "S_%02zu", m);
        cloud::VdbOutputGrid g;
        g.name = name;
        g.values = &v.source[m];
        g.text = {{"fulgur_quantity", "source function S(x, direction): radiance scattered towards the direction"},
                  {"fulgur_units", "W m^-2 sr^-1"},
                  {"fulgur_source", v.source_meaning}};
        g.vectors = {{"fulgur_direction", v.directions[m]}};
        g.numbers = {{"fulgur_direction_index", double(m)}};
        grids.push_back(std::move(g));
    }
    cloud::save_vdb(path, grids,
                    {{"fulgur_scene", v.scene},
                     {"fulgur_length_unit", "m (world space; z up, ground at z = 0)"},
                     {"fulgur_grids", "density at full resolution; S_NN on the lighting grid, one per direction"}});
}

}  // namespace fulgur::app
