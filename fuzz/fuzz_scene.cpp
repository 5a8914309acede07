// libFuzzer harness: the scene reader on arbitrary bytes. Any input must parse or throw
// core::Error; a crash, hang, leak or sanitizer report is a finding.
#include "scene/scene.h"

#include <cstddef>
#include <cstdint>
#include <string_view>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    try {
        (void)fulgur::scene::parse_scene(std::string_view(reinterpret_cast<const char*>(data), size), "fuzz.json");
    } catch (const fulgur::core::Error&) {}
    return 0;
}
