// Timing loop in C++: appell's generated appell_forward (the accelerations, the multipliers and
// every joint's force and moment; the shared library is the first argument) against Pinocchio's
// own C++ aba + rnea (whose data.f are the joint wrenches) on the same URDF file, interleaved
// rounds (benchmarks/robots.py --c-loop builds and runs it).
// usage: bench_robot LIB URDF floating(0/1) iterations nq n np nb s q... w... p...   (prints JSON)
#include <dlfcn.h>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <vector>
#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/algorithm/joint-configuration.hpp>
#include <pinocchio/algorithm/rnea.hpp>
#include <pinocchio/multibody.hpp>
#include <pinocchio/parsers/urdf.hpp>

typedef void (*forward_t)(double, const double *, const double *, const double *, const double *, double *,
                          double *, double *);

static double now() { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); }

int main(int argc, char **argv)
{
    if (argc < 10) return 2;
    void *lib = dlopen(argv[1], RTLD_NOW);
    if (!lib) { std::fprintf(stderr, "%s\n", dlerror()); return 2; }
    forward_t fw = (forward_t)dlsym(lib, "appell_forward");
    if (!fw) { std::fprintf(stderr, "no appell_forward\n"); return 2; }
    pinocchio::Model model;
    if (std::atoi(argv[3])) pinocchio::urdf::buildModel(argv[2], pinocchio::JointModelFreeFlyer(), model);
    else pinocchio::urdf::buildModel(argv[2], model);
    pinocchio::Data data(model);
    const int iters = std::atoi(argv[4]), nq = std::atoi(argv[5]), n = std::atoi(argv[6]), np = std::atoi(argv[7]);
    const int nb = std::atoi(argv[8]), s = std::atoi(argv[9]);
    if (argc != 10 + nq + n + np) { std::fprintf(stderr, "expected %d numbers\n", nq + n + np); return 2; }
    std::vector<double> q(nq), w(n), p(np), acc(n), lam(s + 1), wrench(6 * nb);
    for (int i = 0; i < nq; ++i) q[i] = std::atof(argv[10 + i]);
    for (int i = 0; i < n; ++i) w[i] = std::atof(argv[10 + nq + i]);
    for (int i = 0; i < np; ++i) p[i] = std::atof(argv[10 + nq + n + i]);
    std::srand(1);
    Eigen::VectorXd qp = pinocchio::neutral(model), vp = Eigen::VectorXd::Random(model.nv) * 0.5;
    for (int j = 1; j < (int)model.njoints; ++j)
        if (model.joints[j].nq() == 1) qp[model.joints[j].idx_q()] = 0.3;
    Eigen::VectorXd zero = Eigen::VectorXd::Zero(model.nv);
    double best_a = 1e9, best_p = 1e9, sink = 0.0, ratio[41];
    for (int rep = 0; rep < 41; ++rep) {
        double t0 = now();
        for (int it = 0; it < iters; ++it) { q[0] += 1e-300; fw(0.0, q.data(), w.data(), nullptr, p.data(), acc.data(), lam.data(), wrench.data()); sink += wrench[0]; }
        double t1 = now();
        for (int it = 0; it < iters; ++it) {
            qp[0] += 1e-300;
            pinocchio::aba(model, data, qp, vp, zero);
            pinocchio::rnea(model, data, qp, vp, data.ddq);
            sink += data.tau[0];
        }
        double t2 = now();
        best_a = std::min(best_a, (t1 - t0) / iters);
        best_p = std::min(best_p, (t2 - t1) / iters);
        ratio[rep] = (t1 - t0) / (t2 - t1);
    }
    std::sort(ratio, ratio + 41);
    std::printf("{\"appell_ns\": %.1f, \"pinocchio_ns\": %.1f, \"median_ratio\": %.3f, \"nv\": %d, \"sink\": %g}\n",
                best_a * 1e9, best_p * 1e9, ratio[20], (int)model.nv, sink * 0);
    return 0;
}
