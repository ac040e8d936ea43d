// Bindings for volrig/rig.hpp: autorig, bind, rest matrices. Conversions only.
#include "volrig/rig.hpp"

#include <map>

#include "rig_arrays.hpp"

namespace volrig::py {

namespace {

using EdgeArray = py::array_t<std::uint32_t, py::array::c_style | py::array::forcecast>;

std::vector<std::array<std::uint32_t, 2>> edges_of(const EdgeArray& e) {
    if (e.ndim() != 2 || e.shape(1) != 2) throw Error("tree edges must have shape (M, 2)");
    std::vector<std::array<std::uint32_t, 2>> out(static_cast<std::size_t>(e.shape(0)));
    for (std::size_t k = 0; k < out.size(); ++k) out[k] = {e.data()[2 * k], e.data()[2 * k + 1]};
    return out;
}

py::dict dict_of(Rig&& r) {
    const auto nj = static_cast<py::ssize_t>(r.joints.size()), nb = static_cast<py::ssize_t>(r.bones.size());
    std::vector<double> joints(3 * r.joints.size());
    for (std::size_t j = 0; j < r.joints.size(); ++j)
        for (int a = 0; a < 3; ++a) joints[3 * j + a] = r.joints[j][a];
    std::vector<std::int32_t> bones(2 * r.bones.size());
    for (std::size_t b = 0; b < r.bones.size(); ++b) {
        bones[2 * b] = r.bones[b][0];
        bones[2 * b + 1] = r.bones[b][1];
    }
    py::dict d;
    d["joints"] = to_numpy_shaped(std::move(joints), {nj, 3});
    d["bones"] = to_numpy_shaped(std::move(bones), {nb, 2});
    d["names"] = r.names;
    d["parents"] = to_numpy_shaped(std::move(r.parents), {nb});
    d["kind"] = r.kind;
    d["joint_points"] = to_numpy_shaped(std::move(r.joint_points), {nj});
    d["fit"] = r.fit;
    d["up"] = py::make_tuple(r.up[0], r.up[1], r.up[2]);
    d["up_confidence"] = r.up_confidence;
    d["runner_up"] = r.runner_up;
    d["runner_up_fit"] = r.runner_up_fit;
    d["note"] = r.note;
    return d;
}

py::list joints_of(const std::vector<BoneJoint>& js) {
    py::list out;
    for (const BoneJoint& j : js) {
        py::dict d;
        d["joint"] = j.joint;
        d["name"] = j.name;
        d["from"] = py::make_tuple(j.from[0], j.from[1], j.from[2]);
        d["to"] = py::make_tuple(j.to[0], j.to[1], j.to[2]);
        d["how"] = j.how;
        d["why"] = j.why;
        d["parent_segment"] = j.parent_segment;
        d["child_segment"] = j.child_segment;
        out.append(d);
    }
    return out;
}

BoneRigOptions bone_options(double opening, double min_volume, double reach) {
    BoneRigOptions o;
    o.opening = opening;
    o.min_volume = min_volume;
    o.reach = reach;
    return o;
}

/// Rigs from a scan's bones (volrig/rig.hpp bone_segments, rig_to_bones; python/volrig/bones.py).
void bind_bones(py::module_& m) {
    m.def(
        "bone_segments",
        [](const MaskArray& bone, const Vec3& spacing, const Vec3& origin, double opening, double min_volume) {
            const Grid g = grid_of(bone, spacing, origin, "bone");
            BoneSegments s;
            {
                py::gil_scoped_release nogil;
                s = bone_segments(g, bone.data(), bone_options(opening, min_volume, 0));
            }
            return py::make_tuple(to_numpy_shaped(std::move(s.labels), {bone.shape(0), bone.shape(1), bone.shape(2)}),
                                  to_numpy_shaped(std::move(s.sizes), {static_cast<py::ssize_t>(s.sizes.size())}));
        },
        py::arg("bone"), py::arg("spacing"), py::arg("origin"), py::arg("opening") = 0.0, py::arg("min_volume") = 0.0);

    m.attr("BARE_BONE_SHARE") = kBareBoneShare;
    m.def(
        "bare_bone_share",
        [](const MaskArray& body, const MaskArray& bone) {
            const Grid g = grid_of(body, {1, 1, 1}, {0, 0, 0}, "body");
            if (bone.ndim() != 3 || bone.shape(0) != body.shape(0) || bone.shape(1) != body.shape(1) ||
                bone.shape(2) != body.shape(2))
                throw Error("bare_bone_share: bone and body must be on the same grid");
            py::gil_scoped_release nogil;
            return bare_bone_share(g, body.data(), bone.data());
        },
        py::arg("body"), py::arg("bone"));

    m.def(
        "bone_body",
        [](const MaskArray& bone, const Vec3& spacing, const Vec3& origin) {
            const Grid g = grid_of(bone, spacing, origin, "bone");
            BoneBody b;
            {
                py::gil_scoped_release nogil;
                b = bone_body(g, bone.data());
            }
            return py::make_tuple(
                to_numpy_shaped(std::move(b.mask), {bone.shape(0), bone.shape(1), bone.shape(2)}), b.radius, b.joined);
        },
        py::arg("bone"), py::arg("spacing"), py::arg("origin"));

    m.def(
        "rig_to_bones",
        [](const MaskArray& bone, const Vec3& spacing, const Vec3& origin, const DoubleArray& joints,
           const IntArray& bones, const std::vector<std::string>& names, const IntArray& parents, double opening,
           double min_volume, double reach) {
            const Grid g = grid_of(bone, spacing, origin, "bone");
            const Rig r = rig_of(joints, bones, names, parents);
            BoneRig out;
            {
                py::gil_scoped_release nogil;
                out = rig_to_bones(g, bone.data(), r, bone_options(opening, min_volume, reach));
            }
            std::vector<double> flat(3 * out.rig.joints.size());
            for (std::size_t j = 0; j < out.rig.joints.size(); ++j)
                for (int a = 0; a < 3; ++a) flat[3 * j + a] = out.rig.joints[j][a];
            py::dict d;
            d["joints"] = to_numpy_shaped(std::move(flat), {static_cast<py::ssize_t>(out.rig.joints.size()), 3});
            d["moves"] = joints_of(out.joints);
            d["segments"] = to_numpy_shaped(std::move(out.segments.labels), {bone.shape(0), bone.shape(1), bone.shape(2)});
            d["sizes"] = to_numpy_shaped(std::move(out.segments.sizes), {static_cast<py::ssize_t>(out.segments.sizes.size())});
            d["bone_segment"] = to_numpy_shaped(std::move(out.bone_segment), {static_cast<py::ssize_t>(r.bones.size())});
            return d;
        },
        py::arg("bone"), py::arg("spacing"), py::arg("origin"), py::arg("joints"), py::arg("bones"), py::arg("names"),
        py::arg("parents"), py::arg("opening") = 0.0, py::arg("min_volume") = 0.0, py::arg("reach") = 0.0);
}

/// What autorig worked on (AutorigDetail) into the result's dict.
void add_detail(py::dict& d, AutorigDetail&& detail, std::size_t n_points) {
    d["kept"] = to_numpy_shaped(std::move(detail.kept), {static_cast<py::ssize_t>(n_points)}).attr("view")("bool");
    d["root"] = detail.root;
    std::vector<double> nodes;
    for (const auto& c : detail.nodes) nodes.insert(nodes.end(), c.begin(), c.end());
    std::vector<std::uint32_t> ne;
    for (const auto& ed : detail.node_edges) ne.insert(ne.end(), ed.begin(), ed.end());
    const auto nn = static_cast<py::ssize_t>(detail.nodes.size());
    d["nodes"] = to_numpy_shaped(std::move(nodes), {nn, 3});
    d["node_radius"] = to_numpy_shaped(std::move(detail.node_radius), {nn});
    d["node_edges"] = to_numpy_shaped(std::move(ne), {static_cast<py::ssize_t>(detail.node_edges.size()), 2});
    d["node_kept"] = to_numpy_shaped(std::move(detail.node_kept), {nn}).attr("view")("bool");
    d["reading_kind"] = detail.reading_kind;
    std::vector<double> feats;
    for (const auto& f : detail.reading_features) feats.insert(feats.end(), f.begin(), f.end());
    d["reading_features"] = to_numpy_shaped(std::move(feats), {static_cast<py::ssize_t>(detail.reading_kind.size()),
                        static_cast<py::ssize_t>(autorig_plan_terms().size())});
    std::vector<std::int64_t> leaves(5 * detail.reading_leaves.size(), -1);
    for (std::size_t r = 0; r < detail.reading_leaves.size(); ++r)
        for (std::size_t k = 0; k < std::min<std::size_t>(5, detail.reading_leaves[r].size()); ++k)
            leaves[5 * r + k] = detail.reading_leaves[r][k];
    d["reading_leaves"] = to_numpy_shaped(std::move(leaves), {static_cast<py::ssize_t>(detail.reading_leaves.size()), 5});
    d["chains_fit"] = detail.chains_fit;
}

/// autorig (volrig/rig.hpp; python/volrig/rig.py).
void bind_autorig(py::module_& m) {
    m.def(
        "autorig",
        [](const MaskArray& mask, const Vec3& spacing, const Vec3& origin, const IjkArray& ijk, const FloatArray& radius,
           const EdgeArray& edges, int bones, double prune_scale, double tolerance, bool roles,
           const std::string& kind, const std::optional<Vec3>& up, bool own_scale, const py::object& progress,
           const std::map<std::string, Vec3>& markers, const std::vector<double>& plan_weights, bool want_detail) {
            const Grid g = grid_of(mask, spacing, origin, "mask");
            const PointSet pts = point_set(ijk, &radius, "autorig");
            const auto e = edges_of(edges);
            AutorigOptions opt;
            opt.bones = bones;
            opt.prune_scale = prune_scale;
            opt.tolerance = tolerance;
            opt.roles = roles;
            opt.kind = kind;
            opt.own_scale = own_scale;
            if (up) opt.up = std::array<double, 3>{(*up)[0], (*up)[1], (*up)[2]};
            for (const auto& [name, at] : markers) opt.markers.emplace_back(name, std::array<double, 3>{at[0], at[1], at[2]});
            opt.plan_weights = plan_weights;
            Progress p = progress_of(progress);
            Rig r;
            AutorigDetail detail;  // only when asked for: without it autorig skips work only the detail reports
            {
                py::gil_scoped_release nogil;
                r = autorig(g, mask.data(), pts, e, opt, p, want_detail ? &detail : nullptr);
            }
            py::dict d = dict_of(std::move(r));
            if (want_detail) add_detail(d, std::move(detail), pts.n);
            return d;
        },
        py::arg("mask"), py::arg("spacing"), py::arg("origin"), py::arg("ijk"), py::arg("radius"), py::arg("edges"),
        py::arg("bones"), py::arg("prune_scale"), py::arg("tolerance"), py::arg("roles"), py::arg("kind") = "",
        py::arg("up") = py::none(), py::arg("own_scale") = true, py::arg("progress") = py::none(),
        py::arg("markers") = std::map<std::string, Vec3>{}, py::arg("plan_weights") = std::vector<double>{},
        py::arg("detail") = true);
}

}  // namespace

void bind_rig(py::module_& m) {
    m.attr("AUTORIG_KINDS") = names_tuple(kAutorigKinds);  // spelled once in the core (volrig/rig.hpp)
    m.attr("MARKER_NAMES") = names_tuple(kMarkerNames);
    m.attr("PLAN_TERMS") = py::tuple(py::cast(autorig_plan_terms()));
    m.attr("PLAN_WEIGHTS") = py::tuple(py::cast(autorig_fitted_weights()));
    bind_autorig(m);

    m.def(
        "bind",
        [](const MaskArray& mask, const Vec3& spacing, const Vec3& origin, const IjkArray& ijk, const FloatArray& radius,
           const DoubleArray& joints, const IntArray& bones, const std::vector<std::string>& names,
           const IntArray& parents, const std::string& mode, const py::object& progress,
           const std::optional<MaskArray>& rigid) {
            const Grid g = grid_of(mask, spacing, origin, "mask");
            if (rigid) grid_of(*rigid, spacing, origin, "rigid");
            if (rigid && (rigid->shape(0) != mask.shape(0) || rigid->shape(1) != mask.shape(1) ||
                          rigid->shape(2) != mask.shape(2)))
                throw Error("bind: the rigid tissue must lie on the mask's grid");
            const PointSet pts = point_set(ijk, &radius, "bind");
            const Rig r = rig_of(joints, bones, names, parents);
            BindMode bm;
            if (mode == "rigid") bm = BindMode::Rigid;
            else if (mode == "smooth") bm = BindMode::Smooth;
            else throw Error("bind: mode must be 'rigid' or 'smooth', got '" + mode + "'");
            Progress p = progress_of(progress);
            Binding b;
            {
                py::gil_scoped_release nogil;
                b = volrig::bind(g, mask.data(), pts, r, bm, p, rigid ? rigid->data() : nullptr);
            }
            const auto n = static_cast<py::ssize_t>(pts.n);
            std::vector<std::int32_t> wb(3 * pts.n);
            std::vector<float> w(3 * pts.n);
            for (std::size_t i = 0; i < pts.n; ++i)
                for (int k = 0; k < 3; ++k) {
                    wb[3 * i + k] = b.weight_bones[i][k];
                    w[3 * i + k] = b.weights[i][k];
                }
            return py::make_tuple(to_numpy_shaped(std::move(b.bone), {n}), to_numpy_shaped(std::move(wb), {n, 3}),
                                  to_numpy_shaped(std::move(w), {n, 3}),
                                  to_numpy_shaped(std::move(b.unreachable), {n}).attr("view")("bool"));
        },
        py::arg("mask"), py::arg("spacing"), py::arg("origin"), py::arg("ijk"), py::arg("radius"), py::arg("joints"),
        py::arg("bones"), py::arg("names"), py::arg("parents"), py::arg("mode"), py::arg("progress") = py::none(),
        py::arg("rigid") = py::none());

    bind_bones(m);
    m.def(
        "check_rig",
        [](const DoubleArray& joints, const IntArray& bones, const std::vector<std::string>& names,
           const IntArray& parents) { rig_of(joints, bones, names, parents); },
        py::arg("joints"), py::arg("bones"), py::arg("names"), py::arg("parents"));

    m.def(
        "rest_matrix",
        [](const Vec3& head, const Vec3& tail) {
            const auto m16 = rest_matrix(head, tail);
            std::vector<double> rows(16);  // row-major for numpy
            for (int r = 0; r < 4; ++r)
                for (int c = 0; c < 4; ++c) rows[4 * r + c] = m16[4 * c + r];
            return to_numpy_shaped(std::move(rows), {4, 4});
        },
        py::arg("head"), py::arg("tail"));
}

}  // namespace volrig::py
