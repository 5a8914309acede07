// libFuzzer harness: the NRRD reader on arbitrary bytes, through a memory-backed regular file
// (read_nrrd takes a path and checks it is a regular file of bounded size).
#include "core/core.h"

#include <sys/mman.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    static const int fd = ::memfd_create("fuzz.nrrd", 0);
    static const std::string path = "/proc/self/fd/" + std::to_string(fd);
    if (fd < 0 || ::ftruncate(fd, 0) != 0 || ::pwrite(fd, data, size, 0) != ssize_t(size)) std::abort();
    try {
        (void)fulgur::core::read_nrrd(path);
    } catch (const fulgur::core::Error&) {}
    return 0;
}
