// io/vdb_detail.hpp: what the OpenVDB reader (io/vdb_read.cpp) and writer (io/vdb_write.cpp) share. Not installed;
// not part of the public API.
#pragma once

#include <openvdb/openvdb.h>

namespace volrig::io_detail {

inline void initialize_openvdb() {
    static const bool done = [] {
        openvdb::initialize();
        return true;
    }();
    (void)done;
}

}  // namespace volrig::io_detail
