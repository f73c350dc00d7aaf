// Times Pinocchio's kernels, one thread, on a model (Pinocchio's binary
// serialization of the URDF's model, written by scripts/pinocchio-timing.py
// with the wheel's own URDF parser) and a file of states
// (one line per state: q, then v, then a, 3·nv numbers), the states that
// idexp's criterion bench `benches/robot.rs` uses (it writes them).
//
// usage: pinocchio_timing <model.bin> <states.txt> <label>
// prints one line per kernel: label kernel median_ns min_ns calls_per_batch
#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/joint-configuration.hpp>
#include <pinocchio/algorithm/regressor.hpp>
#include <pinocchio/algorithm/rnea-derivatives.hpp>
#include <pinocchio/algorithm/rnea.hpp>
#include <pinocchio/multibody.hpp>
#include <pinocchio/serialization.hpp>

#include <algorithm>
#include <chrono>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

namespace pin = pinocchio;

template <class T> inline void keep(const T &x) { asm volatile("" : : "g"(&x) : "memory"); }

struct State {
  Eigen::VectorXd q, v, a;
};

// per-call time (ns) of f over the states: `batches` batches of `reps`
// sweeps; median and minimum over the batches
template <class F> std::pair<double, double> time_it(const std::vector<State> &st, F f, int reps, int batches) {
  std::vector<double> per;
  for (int b = 0; b < batches + 2; ++b) {
    auto t0 = std::chrono::steady_clock::now();
    for (int r = 0; r < reps; ++r)
      for (const State &s : st) f(s);
    auto t1 = std::chrono::steady_clock::now();
    if (b >= 2)  // two warm-up batches
      per.push_back(std::chrono::duration<double, std::nano>(t1 - t0).count() / double(reps * st.size()));
  }
  std::sort(per.begin(), per.end());
  return {per[per.size() / 2], per.front()};
}

int main(int argc, char **argv) {
  if (argc != 4) {
    std::cerr << "usage: pinocchio_timing <model.bin> <states.txt> <label>\n";
    return 1;
  }
  pin::Model model;
  model.loadFromBinary(argv[1]);
  pin::Data data(model);
  const int nv = model.nv;
  std::vector<State> st;
  std::ifstream in(argv[2]);
  if (!in) {
    std::cerr << argv[2] << ": cannot open the states file\n";
    return 1;
  }
  std::string line;
  int row = 0;
  while (std::getline(in, line)) {
    ++row;
    std::istringstream ls(line);
    std::vector<double> x;
    double d;
    while (ls >> d) x.push_back(d);
    if (x.empty()) continue;
    if ((int)x.size() != 3 * nv) {
      std::cerr << argv[2] << ": row " << row << " has " << x.size() << " numbers, expected 3·nv = " << 3 * nv << "\n";
      return 1;
    }
    State s;
    s.q = Eigen::Map<Eigen::VectorXd>(x.data(), nv);
    s.v = Eigen::Map<Eigen::VectorXd>(x.data() + nv, nv);
    s.a = Eigen::Map<Eigen::VectorXd>(x.data() + 2 * nv, nv);
    st.push_back(s);
  }
  if (st.empty()) {
    std::cerr << argv[2] << ": no states\n";
    return 1;
  }
  const std::string label = argv[3];
  const int reps = 200, batches = 15;
  auto report = [&](const char *name, std::pair<double, double> t) {
    std::cout << label << " " << name << " " << t.first << " " << t.second << " " << reps * st.size() << "\n";
  };
  // the torques of the states' accelerations, input of forward dynamics
  std::vector<Eigen::VectorXd> tau;
  for (const State &s : st) tau.push_back(pin::rnea(model, data, s.q, s.v, s.a));
  report("rnea", time_it(st, [&](const State &s) { keep(pin::rnea(model, data, s.q, s.v, s.a)); }, reps, batches));
  report("crba", time_it(st, [&](const State &s) { keep(pin::crba(model, data, s.q)); }, reps, batches));
  report("computeJointTorqueRegressor",
         time_it(st, [&](const State &s) { keep(pin::computeJointTorqueRegressor(model, data, s.q, s.v, s.a)); }, reps, batches));
  report("computeRNEADerivatives", time_it(st, [&](const State &s) {
           pin::computeRNEADerivatives(model, data, s.q, s.v, s.a);
           keep(data.dtau_dq);
         }, reps, batches));
  size_t k = 0;
  report("aba", time_it(st, [&](const State &s) {
           keep(pin::aba(model, data, s.q, s.v, tau[k++ % tau.size()]));
         }, reps, batches));
  return 0;
}
