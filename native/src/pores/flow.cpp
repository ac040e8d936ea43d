// Steady transport on a pore network: a sparse symmetric positive definite solve (Eigen).
#include <numeric>

#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>

#include "volrig/pores.hpp"

namespace volrig::pores_detail {

namespace {

/// Disjoint sets over the nodes, joined along the edges.
std::vector<std::size_t> components(std::size_t nodes, const std::int32_t* conns, std::size_t edges) {
    std::vector<std::size_t> parent(nodes);
    std::iota(parent.begin(), parent.end(), std::size_t{0});
    auto find = [&](std::size_t a) {
        while (parent[a] != a) a = parent[a] = parent[parent[a]];
        return a;
    };
    for (std::size_t e = 0; e < edges; ++e) {
        const std::size_t a = find(static_cast<std::size_t>(conns[2 * e])),
                          b = find(static_cast<std::size_t>(conns[2 * e + 1]));
        if (a != b) parent[a] = b;
    }
    for (std::size_t i = 0; i < nodes; ++i) parent[i] = find(i);
    return parent;
}

/// Per node: whether it belongs to a component holding both an inlet and an outlet node.
std::vector<std::uint8_t> spanning(std::size_t nodes, const std::vector<std::size_t>& comp, const std::uint8_t* inlet,
                                   const std::uint8_t* outlet) {
    std::vector<std::uint8_t> flags(nodes, 0);  // bit 1: holds an inlet; bit 2: an outlet
    for (std::size_t i = 0; i < nodes; ++i) {
        if (inlet[i]) flags[comp[i]] |= 1;
        else if (outlet[i]) flags[comp[i]] |= 2;
    }
    std::vector<std::uint8_t> out(nodes);
    for (std::size_t i = 0; i < nodes; ++i) out[i] = flags[comp[i]] == 3 ? 1 : 0;
    return out;
}

}  // namespace

}  // namespace volrig::pores_detail

namespace volrig {

double network_rate(std::size_t nodes, const std::int32_t* conns, const double* g, std::size_t edges,
                    const std::uint8_t* inlet, const std::uint8_t* outlet) {
    for (std::size_t e = 0; e < 2 * edges; ++e)
        if (conns[e] < 0 || static_cast<std::size_t>(conns[e]) >= nodes)
            throw Error("network_rate: a node index out of range");
    for (std::size_t e = 0; e < edges; ++e)
        if (!(g[e] > 0)) throw Error("network_rate: conductances must be positive and finite");
    const std::vector<std::uint8_t> live =
        pores_detail::spanning(nodes, pores_detail::components(nodes, conns, edges), inlet, outlet);
    // Unknowns: the live nodes held at no value.
    std::vector<std::int64_t> unknown(nodes, -1);
    std::int64_t k = 0;
    for (std::size_t i = 0; i < nodes; ++i)
        if (live[i] && !inlet[i] && !outlet[i]) unknown[i] = k++;
    auto fixed = [&](std::size_t i) { return inlet[i] ? 1.0 : 0.0; };
    std::vector<Eigen::Triplet<double>> trip;
    Eigen::VectorXd b = Eigen::VectorXd::Zero(k);
    for (std::size_t e = 0; e < edges; ++e) {
        const auto i = static_cast<std::size_t>(conns[2 * e]), j = static_cast<std::size_t>(conns[2 * e + 1]);
        if (!live[i] || i == j) continue;
        const std::int64_t ui = unknown[i], uj = unknown[j];
        if (ui >= 0) trip.emplace_back(ui, ui, g[e]);
        if (uj >= 0) trip.emplace_back(uj, uj, g[e]);
        if (ui >= 0 && uj >= 0) {
            trip.emplace_back(ui, uj, -g[e]);
            trip.emplace_back(uj, ui, -g[e]);
        } else if (ui >= 0) {
            b[ui] += g[e] * fixed(j);
        } else if (uj >= 0) {
            b[uj] += g[e] * fixed(i);
        }
    }
    Eigen::VectorXd x = Eigen::VectorXd::Zero(k);
    if (k > 0) {
        Eigen::SparseMatrix<double> a(k, k);
        a.setFromTriplets(trip.begin(), trip.end());
        Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(a);
        if (solver.info() != Eigen::Success) throw Error("network_rate: the network's matrix could not be factored");
        x = solver.solve(b);
        if (solver.info() != Eigen::Success) throw Error("network_rate: the solve failed");
    }
    auto value = [&](std::size_t i) { return unknown[i] >= 0 ? x[unknown[i]] : fixed(i); };
    double rate = 0;
    for (std::size_t e = 0; e < edges; ++e) {
        const auto i = static_cast<std::size_t>(conns[2 * e]), j = static_cast<std::size_t>(conns[2 * e + 1]);
        if (!live[i] || inlet[i] == inlet[j]) continue;
        rate += inlet[i] ? g[e] * (1.0 - value(j)) : g[e] * (1.0 - value(i));
    }
    return rate;
}

}  // namespace volrig
