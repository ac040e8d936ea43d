// io/source.cpp: the byte sources readers read from: files on disk (pread, so a header and its data can be read at
// any offset without loading the file) and blocks of memory (fuzzing, tests).
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>

#include "io/io_detail.hpp"
#include "volrig/io.hpp"

namespace volrig {

namespace {

class FileSource final : public ByteSource {
public:
    explicit FileSource(std::string path) : path_(std::move(path)) {
        if (path_.empty()) throw FileNotFound("(empty path): no such file");
        io_detail::check_path(path_);
        // Non-blocking: opening a FIFO must not wait for a writer (it is refused below); regular files ignore it.
        fd_ = ::open(path_.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
        if (fd_ < 0) {
            const int e = errno;
            if (e == ENOENT || e == ENOTDIR) throw FileNotFound(path_ + ": no such file");
            throw FileNotFound(path_ + ": cannot open: " + io_detail::errno_text(e));
        }
        struct stat st {};
        if (::fstat(fd_, &st) != 0) {
            const int e = errno;
            ::close(fd_);
            throw FileNotFound(path_ + ": cannot open: " + io_detail::errno_text(e));
        }
        if (S_ISDIR(st.st_mode)) {
            ::close(fd_);
            throw FileNotFound(path_ + ": is a directory, not a file");
        }
        if (!S_ISREG(st.st_mode)) {
            ::close(fd_);
            throw FileFormatError(path_ + ": not a regular file (" + io_detail::file_kind(st.st_mode) + ")");
        }
        size_ = static_cast<std::uint64_t>(st.st_size);
    }
    ~FileSource() override {
        if (fd_ >= 0) ::close(fd_);
    }
    FileSource(const FileSource&) = delete;
    FileSource& operator=(const FileSource&) = delete;

    std::uint64_t size() const override { return size_; }
    const std::string& name() const override { return path_; }

    void read(std::uint64_t offset, void* dst, std::size_t n) const override {
        if (offset > size_ || n > size_ - offset)
            io_detail::fail(path_, "expected " + io_detail::with_commas(n) + " bytes at offset " +
                                    io_detail::with_commas(offset) + " but the file holds " +
                                    io_detail::with_commas(size_) + " bytes");
        auto* p = static_cast<char*>(dst);
        while (n > 0) {
            const std::size_t step = std::min<std::size_t>(n, std::size_t(1) << 30);
            const ssize_t r = ::pread(fd_, p, step, static_cast<off_t>(offset));
            if (r < 0) {
                if (errno == EINTR) continue;
                io_detail::fail(path_, "read error: " + io_detail::errno_text(errno));
            }
            if (r == 0) io_detail::fail(path_, "the file became shorter while it was being read");
            p += r;
            offset += static_cast<std::uint64_t>(r);
            n -= static_cast<std::size_t>(r);
        }
    }

    std::unique_ptr<ByteSource> open_sibling(const std::string& relative_name) const override {
        if (relative_name.empty()) io_detail::fail(path_, "the data file name is empty");
        for (unsigned char c : relative_name)
            if (c < 0x20 || c == 0x7f)
                io_detail::fail(path_, "data file name " + io_detail::quoted(relative_name) + " contains control characters");
        std::filesystem::path p(relative_name);
        if (!p.is_absolute()) p = std::filesystem::path(path_).parent_path() / p;
        try {
            return std::make_unique<FileSource>(p.string());
        } catch (const FileNotFound& e) {
            throw FileNotFound(path_ + ": data file " + io_detail::quoted(relative_name) + " cannot be opened (" +
                               e.what() + ")");
        }
    }

private:
    std::string path_;
    int fd_ = -1;
    std::uint64_t size_ = 0;
};

class MemorySource final : public ByteSource {
public:
    MemorySource(const std::uint8_t* data, std::size_t n, std::string name)
        : bytes_(data, data + (data ? n : 0)), name_(std::move(name)) {}
    std::uint64_t size() const override { return bytes_.size(); }
    const std::string& name() const override { return name_; }
    void read(std::uint64_t offset, void* dst, std::size_t n) const override {
        if (offset > bytes_.size() || n > bytes_.size() - offset)
            io_detail::fail(name_, "expected " + io_detail::with_commas(n) + " bytes at offset " +
                                    io_detail::with_commas(offset) + " but the data holds " +
                                    io_detail::with_commas(bytes_.size()) + " bytes");
        if (n) std::memcpy(dst, bytes_.data() + offset, n);
    }
    std::unique_ptr<ByteSource> open_sibling(const std::string&) const override {
        io_detail::fail(name_, "detached data files are not available for in-memory input");
    }

private:
    std::vector<std::uint8_t> bytes_;
    std::string name_;
};

}  // namespace

namespace io_detail {

void check_path(const std::string& path) {
    if (path.find('\0') != std::string::npos)
        throw Error(path.substr(0, path.find('\0')) + "...: a file name must not contain a NUL character");
}

std::string file_kind(unsigned mode) {
    if (S_ISFIFO(mode)) return "a FIFO";
    if (S_ISSOCK(mode)) return "a socket";
    if (S_ISCHR(mode)) return "a character device";
    if (S_ISBLK(mode)) return "a block device";
    if (S_ISDIR(mode)) return "a folder";
    return "not a regular file";
}

void check_input_path(const std::string& path) {
    check_path(path);
    struct stat st {};
    if (path.empty() || ::stat(path.c_str(), &st) != 0) {
        const int e = errno;
        if (path.empty() || e == ENOENT || e == ENOTDIR) throw FileNotFound(path + ": no such file or folder");
        throw FileNotFound(path + ": cannot open: " + errno_text(e));
    }
    if (!S_ISREG(st.st_mode) && !S_ISDIR(st.st_mode))
        throw FileFormatError(path + ": " + file_kind(st.st_mode) + ", not a regular file or folder");
}

void check_regular_file(const std::string& path) {
    check_input_path(path);
    struct stat st {};
    if (::stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode)) throw FileNotFound(path + ": is a folder, not a file");
}

}  // namespace io_detail

std::unique_ptr<ByteSource> open_file(const std::string& path) { return std::make_unique<FileSource>(path); }

std::unique_ptr<ByteSource> memory_source(const std::uint8_t* data, std::size_t n, std::string name) {
    return std::make_unique<MemorySource>(data, n, std::move(name));
}

}  // namespace volrig
