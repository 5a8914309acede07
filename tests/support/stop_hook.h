// A bake stopped as a killed one would be, for the checkpoint's tests: the hook throws once the
// checkpoint holds enough lights, so the bake writes no file and leaves its checkpoint.
#pragma once

#include "bake/bake.h"

#include <filesystem>

namespace fulgur::test {

struct Stop {};

/// A checkpoint beside `out`, chunks of 2 lights, and a hook throwing Stop once the checkpoint
/// holds `after` lights; `kept` receives the count after every chunk.
inline bake::BakeOptions stop_after(const std::filesystem::path& out, std::size_t after, std::size_t& kept) {
    bake::BakeOptions o;
    o.checkpoint = bake::checkpoint_path(out);
    o.chunk = 2;
    o.on_checkpoint = [&kept, after](std::size_t lights) {
        kept = lights;
        if (lights >= after) throw Stop{};
    };
    return o;
}

}  // namespace fulgur::test
