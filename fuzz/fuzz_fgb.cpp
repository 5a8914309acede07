// libFuzzer harness: the .fgb reader (header, index, every block) on arbitrary bytes.
#include "basis/basis.h"

#include <cstddef>
#include <cstdint>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    try {
        fulgur::basis::FgbReader r(std::vector<std::uint8_t>(data, data + size), "fuzz.fgb");
        (void)fulgur::basis::load_fgb(r, {});
    } catch (const fulgur::core::Error&) {}
    return 0;
}
