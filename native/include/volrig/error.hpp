// volrig/error.hpp: the exceptions volrig raises. Every message says what is wrong; file errors start with the
// file name.
#pragma once

#include <stdexcept>

namespace volrig {

/// Base of every error volrig raises on bad input or misuse.
struct Error : std::runtime_error {
    using std::runtime_error::runtime_error;
};
/// A file that cannot be read as what it claims to be; the message starts with the file name.
struct FileFormatError : Error {
    using Error::Error;
};
/// A file that does not exist or cannot be opened.
struct FileNotFound : Error {
    using Error::Error;
};
/// Raised when a progress callback asked to stop.
struct Cancelled : Error {
    using Error::Error;
};

}  // namespace volrig
