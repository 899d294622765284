/* Pinocchio's own constrained forward dynamics, timed in C++ (benchmarks/closed_chains.py builds it with
   g++ -O3 -march=native -DNDEBUG against the headers of the pip package `pin` (cmeel.prefix) and Eigen's
   from `cmeel-eigen`, the extra [bench] of pyproject.toml). Header only: Pinocchio's templates are
   compiled in this unit with the flags above, as appell's C is with its own, and nothing crosses into
   the package's prebuilt libraries (whose Eigen objects are laid out for another instruction set).

   The model is the one the Python benchmark times: Python's pin.buildModelAndLegacyConstraintsFromMJCF
   reads the MJCF file, and benchmarks/closed_chains.py writes its joints (parent, type, axis, placement),
   their inertias, gravity and its loop closures (RigidConstraintModel: type, the two joints and
   placements, reference frame) to the text file SPEC, rebuilt here joint by joint. At the state (q, v)
   given on the command line, tau = 0, it times
     * constraintDynamics (initConstraintDynamics once, before the loop, as Pinocchio's examples do);
     * lcaba (computeJointMinimalOrdering once, before the loop),
   with the ProximalSettings (accuracy, mu, iterations) of each that SPEC gives, as benchmarks/closed_chains.py
   calls them from Python. Each is run `iterations` times per round, 41 rounds; the per-call CPU time
   (CLOCK_PROCESS_CPUTIME_ID, as benchmarks/harness.py and reference/bench_loops.c) of the best round
   and the median round is printed as JSON, with the accelerations for the cross-check against Python.

   usage: pinocchio_loop SPEC iterations q[nq]... v[nv]...   (Pinocchio's order: x y z qx qy qz qw)
   SPEC: "settings" accuracy mu iterations (constraintDynamics) accuracy mu iterations (lcaba);
   "gravity" gx gy gz; per joint "joint" parent type ax ay az R[9] p[3] mass c[3] I[9] (type
   FreeFlyer, RX, RY, RZ or RevoluteUnaligned; R row-major; I about the centre of mass); per closure
   "contact" type(3|6) joint1 R1[9] p1[3] joint2 R2[9] p2[3] frame(0 WORLD, 1 LOCAL, 2 LOCAL_WORLD_ALIGNED). */
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "pinocchio/algorithm/constrained-dynamics.hpp"
#include "pinocchio/algorithm/loop-constrained-aba.hpp"
#include "pinocchio/multibody.hpp"

using namespace pinocchio;

static double now()
{
  timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

/* best and median per-call seconds of `rounds` rounds of `iters` calls of f */
template<class F>
static void timed(F f, int iters, int rounds, double & best, double & mid)
{
  std::vector<double> per;
  for (int r = 0; r < rounds; ++r)
  {
    const double t0 = now();
    for (int i = 0; i < iters; ++i)
      f();
    per.push_back((now() - t0) / iters);
  }
  std::sort(per.begin(), per.end());
  best = per.front();
  mid = per[per.size() / 2];
}

static void print_vector(const char * name, const Eigen::VectorXd & x)
{
  std::printf("\"%s\": [", name);
  for (Eigen::Index i = 0; i < x.size(); ++i)
    std::printf("%s%.17g", i ? ", " : "", x[i]);
  std::printf("]");
}

static SE3 read_placement(std::istream & in)
{
  Eigen::Matrix3d R;
  Eigen::Vector3d p;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      in >> R(i, j);
  in >> p[0] >> p[1] >> p[2];
  return SE3(R, p);
}

/* the model and its closures from SPEC (the file's comment) */
static void read_spec(const char * path, Model & model, std::vector<RigidConstraintModel> & cmodels,
                      double settings[6])
{
  std::ifstream in(path);
  std::string word;
  while (in >> word)
  {
    if (word == "settings")
    {
      for (int i = 0; i < 6; ++i)
        in >> settings[i];
    }
    else if (word == "gravity")
    {
      Eigen::Vector3d g;
      in >> g[0] >> g[1] >> g[2];
      model.gravity.linear(g);
    }
    else if (word == "joint")
    {
      int parent;
      std::string type;
      Eigen::Vector3d axis, c;
      double mass;
      Eigen::Matrix3d I;
      in >> parent >> type >> axis[0] >> axis[1] >> axis[2];
      const SE3 placement = read_placement(in);
      in >> mass >> c[0] >> c[1] >> c[2];
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
          in >> I(i, j);
      const std::string name = "joint" + std::to_string(model.njoints);
      JointIndex id;
      if (type == "FreeFlyer")
        id = model.addJoint(parent, JointModelFreeFlyer(), placement, name);
      else if (type == "RX")
        id = model.addJoint(parent, JointModelRX(), placement, name);
      else if (type == "RY")
        id = model.addJoint(parent, JointModelRY(), placement, name);
      else if (type == "RZ")
        id = model.addJoint(parent, JointModelRZ(), placement, name);
      else if (type == "RevoluteUnaligned")
        id = model.addJoint(parent, JointModelRevoluteUnaligned(axis), placement, name);
      else
        throw std::runtime_error("joint type not rebuilt here: " + type);
      model.appendBodyToJoint(id, Inertia(mass, c, I), SE3::Identity());
    }
    else if (word == "contact")
    {
      int type, j1, j2, frame;
      in >> type >> j1;
      const SE3 p1 = read_placement(in);
      in >> j2;
      const SE3 p2 = read_placement(in);
      in >> frame;
      const ReferenceFrame frames[3] = {WORLD, LOCAL, LOCAL_WORLD_ALIGNED};
      cmodels.push_back(RigidConstraintModel(type == 6 ? CONTACT_6D : CONTACT_3D, model, JointIndex(j1), p1,
                                             JointIndex(j2), p2, frames[frame]));
    }
    else
      throw std::runtime_error("unknown word in the model file: " + word);
  }
}

int main(int argc, char ** argv)
{
  if (argc < 3)
    return 2;
  Model model;
  std::vector<RigidConstraintModel> cmodels;
  double settings[6] = {1e-12, 1e-12, 3, 1e-12, 1e-4, 100};
  read_spec(argv[1], model, cmodels, settings);
  const int iters = std::atoi(argv[2]);
  if (argc != 3 + model.nq + model.nv)
  {
    std::fprintf(stderr, "expected %d numbers (nq %d, nv %d)\n", model.nq + model.nv, model.nq, model.nv);
    return 2;
  }
  Eigen::VectorXd q(model.nq), v(model.nv), tau = Eigen::VectorXd::Zero(model.nv);
  for (int i = 0; i < model.nq; ++i)
    q[i] = std::atof(argv[3 + i]);
  for (int i = 0; i < model.nv; ++i)
    v[i] = std::atof(argv[3 + model.nq + i]);
  const int rounds = 41;
  double sink = 0.0;

  Data data(model);
  std::vector<RigidConstraintData> cdatas;
  for (const auto & c : cmodels)
    cdatas.push_back(RigidConstraintData(c));
  ProximalSettings prox(settings[0], settings[1], int(settings[2]));
  ProximalSettings lprox(settings[3], settings[4], int(settings[5]));
  initConstraintDynamics(model, data, cmodels, cdatas);
  const Eigen::VectorXd a_cd = constraintDynamics(model, data, q, v, tau, cmodels, cdatas, prox);
  const Eigen::VectorXd lam_cd = data.lambda_c;
  double cd_best, cd_mid;
  timed([&] {
    q[0] += 1e-300;
    sink += constraintDynamics(model, data, q, v, tau, cmodels, cdatas, prox)[0];
  }, iters, rounds, cd_best, cd_mid);

  Data ldata(model);
  std::vector<RigidConstraintData> ldatas;
  for (const auto & c : cmodels)
    ldatas.push_back(RigidConstraintData(c));
  computeJointMinimalOrdering(model, ldata, cmodels);
  const Eigen::VectorXd a_lc = lcaba(model, ldata, q, v, tau, cmodels, ldatas, lprox);
  double lc_best, lc_mid;
  timed([&] {
    q[0] += 1e-300;
    sink += lcaba(model, ldata, q, v, tau, cmodels, ldatas, lprox)[0];
  }, iters, rounds, lc_best, lc_mid);

  std::printf("{\"nq\": %d, \"nv\": %d, \"constraints\": %zu, ", model.nq, model.nv, cmodels.size());
  std::printf("\"constraintDynamics_ns\": [%.1f, %.1f], \"lcaba_ns\": [%.1f, %.1f], ", cd_best * 1e9, cd_mid * 1e9,
              lc_best * 1e9, lc_mid * 1e9);
  print_vector("a_constraintDynamics", a_cd);
  std::printf(", ");
  print_vector("lambda_constraintDynamics", lam_cd);
  std::printf(", ");
  print_vector("a_lcaba", a_lc);
  std::printf(", \"sink\": %g}\n", sink * 0.0);
  return 0;
}
