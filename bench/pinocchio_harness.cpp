// Timing harness for Pinocchio's C++ algorithms on a URDF serial arm (bench/run.py compiles
// and runs it), the counterpart of bench/harness.c for the generated C.
//
// Compiled as (run.py does this, and prints the full command; PREFIX = site-packages/cmeel.prefix
// of the pin wheel, EIGEN3 = PREFIX/include/eigen3 from cmeel-eigen):
//   g++ -std=c++17 -O2 -DNDEBUG [-DPINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION]
//       -DBOOST_MPL_LIMIT_LIST_SIZE=30 -DBOOST_MPL_LIMIT_VECTOR_SIZE=30 -DPINOCCHIO_WITH_URDFDOM ...
//       -I PREFIX/include -I PREFIX/include/urdfdom_headers -I EIGEN3 bench/pinocchio_harness.cpp
//       -L PREFIX/lib -Wl,-rpath,PREFIX/lib -lpinocchio_parsers -lpinocchio_default
// With PINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION (what the wheel's CMake target sets) the
// algorithms are the wheel's own compiled instantiations in libpinocchio_default.so; without
// it they are instantiated from the headers in this translation unit, at this -O level.
//
// Usage:
//   pinocchio_harness URDF TIP [--lock J1,J2,...] [FUNCTION...]   time, print JSON
//   pinocchio_harness URDF TIP [--lock ...] --eval < STATE         evaluate once, print JSON
// FUNCTION in: mass inverse_dynamics gravity jacobian coriolis forward_dynamics (default all).
// --lock: joints locked at q = 0 with buildReducedModel (a gripper's fingers, as robotgen does).
// STATE (for --eval): 3*nq numbers q, qd, x; forward_dynamics uses x as tau, inverse_dynamics
// as qdd.
//
// Timing, as in harness.c: NSETS input sets from the same LCG as harness.c (angles in
// [-pi, pi], rates and accelerations/torques in [-2, 2]: the very states the C side gets) are
// cycled through; one output element per call goes into an accumulator stored to
// a volatile sink; the loop is calibrated to >= 50 ms and repeated REPEATS times; min and
// median ns per call. Only the algorithm call is timed (crba fills the upper triangle of
// data.M, as Pinocchio users get it; symmetrising is not part of the call).
#include <pinocchio/algorithm/aba-derivatives.hpp>
#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/algorithm/model.hpp>
#include <pinocchio/algorithm/rnea-derivatives.hpp>
#include <pinocchio/algorithm/rnea.hpp>
#include <pinocchio/multibody.hpp>
#include <pinocchio/parsers/urdf.hpp>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

namespace {

// Vector arguments are passed as Eigen::Ref<const VectorXd>: the argument types of the wheel's
// explicit instantiations (crba and aba are only found in the library with these; with plain
// VectorXd they would be instantiated here from the headers). The frame Jacobian's
// instantiation takes VectorXd and Matrix6x, which are passed as they are.
using CRef = Eigen::Ref<const Eigen::VectorXd>;

constexpr int NSETS = 256;  // power of two
constexpr int REPEATS = 7;
constexpr double MIN_NS = 5.0e7;

volatile double sink;

double now_ns() {
  timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return double(t.tv_sec) * 1e9 + double(t.tv_nsec);
}

unsigned long long lcg_state = 88172645463325252ULL;
double uniform(double lo, double hi) {
  lcg_state = lcg_state * 6364136223846793005ULL + 1442695040888963407ULL;
  return lo + (hi - lo) * double(lcg_state >> 11) * (1.0 / 9007199254740992.0);
}

struct Timing {
  double ns_min, ns_median;
  long iterations;
};

// call(s) runs the algorithm on input set s and returns one element of its output.
template <class Call>
Timing bench(Call call) {
  long iters = 1000;
  double acc = 0.0, times[REPEATS];
  for (;;) {  // calibrate
    double t0 = now_ns();
    for (long it = 0; it < iters; it++) acc += call(int(it & (NSETS - 1)), it);
    double t1 = now_ns();
    if (t1 - t0 >= MIN_NS || iters > (1L << 30)) break;
    iters *= 2;
  }
  for (int r = 0; r < REPEATS; r++) {
    double t0 = now_ns();
    for (long it = 0; it < iters; it++) acc += call(int(it & (NSETS - 1)), it);
    double t1 = now_ns();
    times[r] = (t1 - t0) / double(iters);
  }
  sink = sink + acc;
  std::sort(times, times + REPEATS);
  return {times[0], times[REPEATS / 2], iters};
}

void json_matrix(std::ostream &os, const Eigen::MatrixXd &m) {  // row-major nested lists
  os << "[";
  for (Eigen::Index i = 0; i < m.rows(); i++) {
    os << (i ? ", [" : "[");
    for (Eigen::Index j = 0; j < m.cols(); j++) os << (j ? ", " : "") << m(i, j);
    os << "]";
  }
  os << "]";
}

std::vector<std::string> split(const std::string &s, char sep) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, sep))
    if (!item.empty()) out.push_back(item);
  return out;
}

}  // namespace

int main(int argc, char **argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: %s URDF TIP [--lock J1,J2] [--eval | FUNCTION...]\n", argv[0]);
    return 2;
  }
  const std::string urdf = argv[1], tip = argv[2];
  std::vector<std::string> locked, functions;
  bool eval = false;
  for (int i = 3; i < argc; i++) {
    if (std::strcmp(argv[i], "--lock") == 0 && i + 1 < argc)
      locked = split(argv[++i], ',');
    else if (std::strcmp(argv[i], "--eval") == 0)
      eval = true;
    else
      functions.push_back(argv[i]);
  }
  if (functions.empty())
    functions = {"mass", "inverse_dynamics", "gravity", "jacobian", "coriolis", "forward_dynamics"};

  pinocchio::Model full;
  pinocchio::urdf::buildModel(urdf, full);
  pinocchio::Model model;
  if (locked.empty()) {
    model = full;
  } else {
    std::vector<pinocchio::JointIndex> ids;
    for (const auto &name : locked) {
      if (!full.existJointName(name)) {
        std::fprintf(stderr, "pinocchio_harness: no joint '%s' in %s\n", name.c_str(), urdf.c_str());
        return 1;
      }
      ids.push_back(full.getJointId(name));
    }
    Eigen::VectorXd q0 = Eigen::VectorXd::Zero(full.nq);
    model = pinocchio::buildReducedModel(full, ids, q0);
  }
  if (!model.existFrame(tip)) {
    std::fprintf(stderr, "pinocchio_harness: no frame '%s' in %s\n", tip.c_str(), urdf.c_str());
    return 1;
  }
  const pinocchio::FrameIndex fid = model.getFrameId(tip);
  pinocchio::Data data(model);
  const int nq = model.nq, nv = model.nv;
  if (nq != nv) {
    std::fprintf(stderr, "pinocchio_harness: nq != nv (%d, %d): not a chain of 1-dof joints\n", nq, nv);
    return 1;
  }
  pinocchio::Data::Matrix6x J = pinocchio::Data::Matrix6x::Zero(6, nv);

  if (eval) {
    Eigen::VectorXd q(nq), v(nv), x(nv);
    for (int i = 0; i < nq; i++) std::cin >> q[i];
    for (int i = 0; i < nv; i++) std::cin >> v[i];
    for (int i = 0; i < nv; i++) std::cin >> x[i];
    if (!std::cin) {
      std::fprintf(stderr, "pinocchio_harness: --eval needs %d numbers on stdin\n", 3 * nq);
      return 1;
    }
    std::ostringstream os;
    os.precision(17);
    os << "{\"nq\": " << nq << ", \"mass\": ";
    pinocchio::crba(model, data, CRef(q));
    Eigen::MatrixXd M = data.M;
    M.triangularView<Eigen::StrictlyLower>() = M.transpose().triangularView<Eigen::StrictlyLower>();
    json_matrix(os, M);
    os << ", \"inverse_dynamics\": ";
    json_matrix(os, pinocchio::rnea(model, data, CRef(q), CRef(v), CRef(x)).transpose());
    os << ", \"gravity\": ";
    json_matrix(os, pinocchio::computeGeneralizedGravity(model, data, CRef(q)).transpose());
    os << ", \"jacobian\": ";
    J.setZero();
    pinocchio::computeFrameJacobian(model, data, q, fid, pinocchio::LOCAL_WORLD_ALIGNED, J);
    json_matrix(os, J);
    os << ", \"coriolis\": ";
    json_matrix(os, pinocchio::computeCoriolisMatrix(model, data, CRef(q), CRef(v)));
    os << ", \"forward_dynamics\": ";
    json_matrix(os, pinocchio::aba(model, data, CRef(q), CRef(v), CRef(x)).transpose());
    os << "}\n";
    std::cout << os.str();
    return 0;
  }

  std::vector<Eigen::VectorXd> Q(NSETS, Eigen::VectorXd(nq)), V(NSETS, Eigen::VectorXd(nv)),
      A(NSETS, Eigen::VectorXd(nv));
  for (int s = 0; s < NSETS; s++)  // the order of harness.c: q, qd, qdd per joint
    for (int i = 0; i < nq; i++) {
      Q[s][i] = uniform(-3.141592653589793, 3.141592653589793);
      V[s][i] = uniform(-2.0, 2.0);
      A[s][i] = uniform(-2.0, 2.0);
    }

  std::ostringstream os;
  os.precision(10);
  os << "{\"nq\": " << nq << ", \"frame\": \"" << tip << "\", \"template_instantiation\": "
#ifdef PINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION
     << "\"library\""
#else
     << "\"header\""
#endif
     << ", \"results\": {";
  bool first = true;
  for (const auto &fn : functions) {
    Timing t;
    const int n = nv;
    if (fn == "mass")
      t = bench([&](int s, long it) { return pinocchio::crba(model, data, CRef(Q[s]))(it % n, n - 1); });
    else if (fn == "inverse_dynamics")
      t = bench([&](int s, long it) { return pinocchio::rnea(model, data, CRef(Q[s]), CRef(V[s]), CRef(A[s]))[it % n]; });
    else if (fn == "gravity")
      t = bench([&](int s, long it) { return pinocchio::computeGeneralizedGravity(model, data, CRef(Q[s]))[it % n]; });
    else if (fn == "jacobian")
      t = bench([&](int s, long it) {
        pinocchio::computeFrameJacobian(model, data, Q[s], fid, pinocchio::LOCAL_WORLD_ALIGNED, J);
        return J(it % 6, (it / 6) % n);
      });
    else if (fn == "coriolis")
      t = bench([&](int s, long it) {
        return pinocchio::computeCoriolisMatrix(model, data, CRef(Q[s]), CRef(V[s]))(it % n, (it / n) % n);
      });
    else if (fn == "forward_dynamics")
      t = bench([&](int s, long it) { return pinocchio::aba(model, data, CRef(Q[s]), CRef(V[s]), CRef(A[s]))[it % n]; });
    else if (fn == "inverse_dynamics_derivatives")
      t = bench([&](int s, long it) {
        pinocchio::computeRNEADerivatives(model, data, Q[s], V[s], A[s]);
        return data.dtau_dq(it % n, (it / n) % n) + data.dtau_dv(it % n, (it / n) % n);
      });
    else if (fn == "forward_dynamics_derivatives")
      t = bench([&](int s, long it) {
        pinocchio::computeABADerivatives(model, data, Q[s], V[s], A[s]);
        return data.ddq_dq(it % n, (it / n) % n) + data.ddq_dv(it % n, (it / n) % n) + data.Minv(0, it % n);
      });
    else {
      std::fprintf(stderr, "pinocchio_harness: unknown function '%s'\n", fn.c_str());
      return 2;
    }
    os << (first ? "" : ", ") << "\"" << fn << "\": {\"ns_min\": " << t.ns_min
       << ", \"ns_median\": " << t.ns_median << ", \"iterations\": " << t.iterations << "}";
    first = false;
  }
  os << "}}\n";
  std::cout << os.str();
  return sink == 12345.678 ? 1 : 0;
}
