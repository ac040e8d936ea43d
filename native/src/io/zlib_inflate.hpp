// io/zlib_inflate.hpp: zlib/gzip streams for the volume readers and writers.
//
// Inflating: streams a zlib or gzip stream (auto-detected; concatenated gzip members allowed) from a range of a
// ByteSource, in chunks, straight into caller buffers. It never writes past the size the caller expects:
// a stream that would produce more fails with "more data than the header declares" (how gzip bombs die), one
// that ends early with "truncated: N of M bytes", a corrupt one with zlib's message.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "volrig/io.hpp"

struct z_stream_s;

namespace volrig::io_detail {

class FileWriter;

/// Deflate expands at most ~1032:1. Refuses (FileFormatError naming `name`) when `expected` decompressed bytes
/// cannot come out of `compressed` bytes: "header declares X bytes but Y compressed bytes can inflate to at
/// most Z". Call before allocating.
void check_inflate_bound(const std::string& name, std::uint64_t expected, std::uint64_t compressed);

/// A decompressing reader over src[offset, offset + length).
class Inflater {
public:
    /// `name` is the subject of error messages; `expected_total` is the full decompressed size the header
    /// declares (used in "truncated: N of M bytes").
    Inflater(const ByteSource& src, std::uint64_t offset, std::uint64_t length, std::string name,
             std::uint64_t expected_total);
    ~Inflater();
    Inflater(const Inflater&) = delete;
    Inflater& operator=(const Inflater&) = delete;

    /// Fills dst with exactly n decompressed bytes, or throws "truncated".
    void read(void* dst, std::size_t n);
    /// Discards n decompressed bytes, or throws "truncated".
    void skip(std::uint64_t n);
    /// Checks that the stream ends here: throws "more data than the header declares" when it would produce
    /// more, and "truncated" when the compressed bytes stop before the stream's end marker.
    void finish();
    std::uint64_t produced() const { return produced_; }
    /// Updates the full decompressed size the header declares (once it is known).
    void expect(std::uint64_t total) { expected_ = total; }

private:
    std::size_t read_some(void* dst, std::size_t n);
    bool refill();
    [[noreturn]] void truncated() const;

    const ByteSource& src_;
    std::string name_;
    std::uint64_t expected_;
    std::uint64_t in_pos_, in_end_;  // unread compressed range of src_
    std::vector<std::uint8_t> in_;
    z_stream_s* z_ = nullptr;
    std::uint64_t produced_ = 0;
    bool ended_ = false;       // stream end reached (no further gzip member)
    bool incomplete_ = false;  // compressed bytes ran out before the end marker
};

/// Inflates src[offset, offset + length) into dst, which must receive exactly `expected` bytes.
void inflate_into(const ByteSource& src, std::uint64_t offset, std::uint64_t length, const std::string& name,
                  void* dst, std::size_t expected);

/// Deflate-compresses `n` bytes produced chunk by chunk into `out`: zlib format, or gzip when `gzip`.
/// Returns the number of compressed bytes written.
class Deflater {
public:
    Deflater(FileWriter& out, bool gzip);
    ~Deflater();
    Deflater(const Deflater&) = delete;
    Deflater& operator=(const Deflater&) = delete;
    void write(const void* data, std::size_t n);
    /// Flushes the stream end; returns the compressed size.
    std::uint64_t finish();

private:
    void pump(int flush);
    FileWriter& out_;
    z_stream_s* z_ = nullptr;
    std::vector<std::uint8_t> buf_;
    std::uint64_t written_ = 0;
};

}  // namespace volrig::io_detail
