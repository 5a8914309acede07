// The .fgb writer: streams blocks (any order, several threads) to a temporary beside the
// file (core::AtomicFile), then writes index and header and renames the file into place; and the merge of partial files, which
// copies their checked blocks unchanged. Encoding is in fgb_codec.cpp.
#include "basis/detail/fgb_codec.h"
#include "basis/fgb.h"

#include <algorithm>
#include <mutex>

namespace fulgur::basis {

using fgb::ByteWriter;
using fgb::describe_range;
using fgb::Header;

struct FgbWriter::Impl {
    struct Entry {
        std::uint64_t offset = 0, size = 0;
        std::uint32_t crc = 0;
        bool present = false;
    };
    std::filesystem::path path;
    FgbMetadata meta;
    std::vector<std::uint8_t> meta_bytes;
    std::uint32_t begin = 0, end = 0;
    std::vector<Entry> entries;
    std::uint64_t cursor = 0;
    std::unique_ptr<core::AtomicFile> file;
    std::mutex mutex;
    bool finished = false;

    void write_at(std::uint64_t offset, const void* p, std::size_t n) {
        file->seek(offset);
        file->write(p, n);
    }
    std::uint64_t index_offset() const { return fgb::kHeaderSize + meta_bytes.size(); }
    std::uint64_t blocks_offset() const { return index_offset() + std::uint64_t(end - begin) * fgb::kIndexEntrySize; }
};

FgbWriter::FgbWriter(std::filesystem::path path, FgbMetadata meta)
    : FgbWriter(std::move(path), meta, 0, std::uint32_t(meta.light_count())) {}

FgbWriter::FgbWriter(std::filesystem::path path, FgbMetadata meta, std::uint32_t light_begin, std::uint32_t light_end)
    : impl_(std::make_unique<Impl>()) {
    Impl& w = *impl_;
    validate(meta, "fgb writer: metadata");
    if (!(light_begin < light_end && light_end <= meta.light_count()))
        throw core::Error(path.string(), "light range " + describe_range(light_begin, light_end) +
                                             " is empty or outside the " + std::to_string(meta.light_count()) +
                                             " virtual lights");
    w.path = std::move(path);
    w.meta = std::move(meta);
    w.meta_bytes = fgb::encode_metadata(w.meta);
    w.begin = light_begin;
    w.end = light_end;
    w.entries.resize(light_end - light_begin);
    w.file = std::make_unique<core::AtomicFile>(w.path);
    // Placeholder header and index, filled by finish().
    const std::vector<std::uint8_t> zeros(std::size_t(w.blocks_offset()), 0);
    w.write_at(0, zeros.data(), zeros.size());
    w.cursor = w.blocks_offset();
}

FgbWriter::~FgbWriter() = default;  // an unfinished file's temporary goes with its AtomicFile

const FgbMetadata& FgbWriter::metadata() const noexcept { return impl_->meta; }

void FgbWriter::add(const CompressedLight& light) { add(encode_block(light, impl_->meta)); }

void FgbWriter::add(const EncodedBlock& block) {
    Impl& w = *impl_;
    std::lock_guard lock(w.mutex);
    FULGUR_ASSERT(!w.finished, "FgbWriter::add after finish()");
    if (block.light < w.begin || block.light >= w.end)
        throw core::Error(w.path.string(), "light " + std::to_string(block.light) + " is outside this file's range " +
                                               describe_range(w.begin, w.end));
    Impl::Entry& e = w.entries[block.light - w.begin];
    if (e.present) throw core::Error(w.path.string(), "light " + std::to_string(block.light) + " was added twice");
    w.write_at(w.cursor, block.bytes.data(), block.bytes.size());
    e.offset = w.cursor;
    e.size = block.bytes.size();
    e.crc = block.crc;
    e.present = true;
    w.cursor += block.bytes.size();
}

void FgbWriter::finish() {
    Impl& w = *impl_;
    std::lock_guard lock(w.mutex);
    FULGUR_ASSERT(!w.finished, "FgbWriter::finish called twice");
    std::size_t missing = 0, first_missing = 0;
    for (std::size_t i = 0; i < w.entries.size(); ++i)
        if (!w.entries[i].present && missing++ == 0) first_missing = w.begin + i;
    if (missing)
        throw core::Error(w.path.string(), std::to_string(missing) + " of the lights " +
                                               describe_range(w.begin, w.end) + " were never added (first: light " +
                                               std::to_string(first_missing) + ")");
    Header h;
    h.file_size = w.cursor;
    h.scene_hash = w.meta.key.hash;
    h.light_count = std::uint32_t(w.meta.light_count());
    h.light_begin = w.begin;
    h.light_end = w.end;
    h.flags = (w.begin == 0 && w.end == h.light_count) ? 0u : fgb::kFlagPartial;
    h.meta_offset = fgb::kHeaderSize;
    h.meta_size = w.meta_bytes.size();
    h.index_offset = w.index_offset();
    h.index_size = std::uint64_t(w.end - w.begin) * fgb::kIndexEntrySize;
    h.blocks_offset = w.blocks_offset();
    h.blocks_size = w.cursor - h.blocks_offset;

    std::vector<std::uint8_t> head = fgb::encode_header(h);
    head.insert(head.end(), w.meta_bytes.begin(), w.meta_bytes.end());
    ByteWriter index;
    for (std::size_t i = 0; i < w.entries.size(); ++i) {
        index.put(w.entries[i].offset);
        index.put(w.entries[i].size);
        index.put(w.entries[i].crc);
        index.put(std::uint32_t(w.begin + i));
    }
    head.insert(head.end(), index.bytes.begin(), index.bytes.end());
    fgb::poke(head, fgb::kOffHeaderCrc, fgb::header_crc(head, h.blocks_offset));
    w.write_at(0, head.data(), head.size());
    w.file->commit();
    w.finished = true;
}

void merge_fgb(const std::filesystem::path& out, std::span<const std::filesystem::path> parts) {
    if (parts.empty()) throw core::Error(out.string(), "merge needs at least one partial file");
    std::vector<FgbReader> readers;
    readers.reserve(parts.size());
    for (const auto& p : parts) readers.emplace_back(p);
    std::sort(readers.begin(), readers.end(),
              [](const FgbReader& a, const FgbReader& b) { return a.light_begin() < b.light_begin(); });
    const FgbMetadata& meta = readers.front().metadata();
    for (std::size_t i = 0; i < readers.size(); ++i) {
        if (!(readers[i].metadata() == meta))
            throw core::Error(readers[i].name(),
                              "cannot merge: its metadata (scene key, grids, directions or compression) "
                              "differs from " +
                                  readers.front().name() + "'s");
        if (i > 0 && readers[i].light_begin() != readers[i - 1].light_end())
            throw core::Error(
                readers[i].name(),
                std::string("cannot merge: lights ") +
                    describe_range(readers[i].light_begin(), readers[i].light_end()) +
                    (readers[i].light_begin() < readers[i - 1].light_end() ? " overlap " : " leave a gap after ") +
                    readers[i - 1].name() + "'s " +
                    describe_range(readers[i - 1].light_begin(), readers[i - 1].light_end()));
    }
    FgbWriter writer(out, meta, readers.front().light_begin(), readers.back().light_end());
    for (FgbReader& r : readers)
        for (std::uint32_t l = r.light_begin(); l < r.light_end(); ++l) writer.add(r.read_encoded(l));
    writer.finish();
}

}  // namespace fulgur::basis
