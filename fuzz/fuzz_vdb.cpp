// libFuzzer harness: the OpenVDB import (inspect_vdb, load_vdb) on arbitrary bytes, through its
// containment: OpenVDB's reader runs in a forked child under memory and time limits, so a
// crash, an overrun or a hang of the library on these bytes is a refusal (core::Error naming
// the file), not a finding. A finding is anything else: a crash, leak or sanitizer report in
// this process (the parent reading the child's records), a hang past the child's time limit,
// or a loaded grid whose size or values break load_vdb's promise. The bytes go to a regular
// temporary file: the child opens the path itself.
#include "cloud/cloud.h"

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <system_error>

namespace {

struct TempFile {
    std::filesystem::path path =
        std::filesystem::temp_directory_path() / ("fulgur_fuzz_vdb_" + std::to_string(::getpid()) + ".vdb");
    ~TempFile() {
        std::error_code ec;
        std::filesystem::remove(path, ec);
    }
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    static const TempFile file;
    {
        std::ofstream f(file.path, std::ios::binary | std::ios::trunc);
        f.write(reinterpret_cast<const char*>(data), std::streamsize(size));
        if (!f) std::abort();
    }
    fulgur::cloud::VdbImport o;
    o.max_bytes = std::uint64_t(256) << 20;  // the load's (and the child's) memory budget
    try {
        (void)fulgur::cloud::inspect_vdb(file.path, o);
    } catch (const fulgur::core::Error&) {}
    try {
        const fulgur::core::Grid3<float> g = fulgur::cloud::load_vdb(file.path, o);
        if (g.data.size() != g.geom.cell_count()) std::abort();
        for (const float v : g.data)
            if (!(v >= 0.0f && v <= 1.0f)) std::abort();
    } catch (const fulgur::core::Error&) {}
    return 0;
}
