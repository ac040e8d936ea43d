// Catch2 v2's single header, for builds against Catch2 v3 (Debian 13): CMakeLists puts this folder on the include
// path only when it finds Catch2 3, and links Catch2::Catch2WithMain (main.cpp's CATCH_CONFIG_MAIN does nothing
// there). The tests use v2's spellings; these are v3's equivalents.
#pragma once
#include <catch2/catch_all.hpp>

#include <string>

namespace Catch {
inline Matchers::StringContainsMatcher Contains(const std::string& s, CaseSensitive cs = CaseSensitive::Yes) {
    return Matchers::ContainsSubstring(s, cs);
}
using Matchers::EndsWith;
using Matchers::StartsWith;
}  // namespace Catch

using Catch::Approx;
