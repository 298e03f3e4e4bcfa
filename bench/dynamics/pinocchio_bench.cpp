// Pinocchio's C++ on the URDF and state of armature's `cargo bench -p armature-kinematics
// --bench dynamics`: RNEA, CRBA, ABA, RNEA and ABA derivatives, median of 21 batches.
// Built and run by pinocchio_bench.sh (pip `pin` and `cmeel-eigen`; not part of the tests).
#include <pinocchio/multibody.hpp>
#include <pinocchio/algorithm/aba-derivatives.hpp>
#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/rnea-derivatives.hpp>
#include <pinocchio/algorithm/rnea.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

template <typename F> double median_ns(F f) {
  std::vector<double> t;
  const int reps = 200000;
  for (int b = 0; b < 21; ++b) {
    auto s = std::chrono::steady_clock::now();
    for (int i = 0; i < reps; ++i) f();
    auto e = std::chrono::steady_clock::now();
    t.push_back(std::chrono::duration<double, std::nano>(e - s).count() / reps);
  }
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

// The model as pinocchio_bench.sh dumps it from Pinocchio's own URDF parser (the wheel has no
// urdfdom headers): per joint, its type (RX/RY/RZ), placement (p, R row-major) and inertia
// (mass, lever, Ixx Ixy Ixz Iyy Iyz Izz), added with the same joint models the parser chooses.
pinocchio::Model load(const char *path) {
  pinocchio::Model model;
  std::ifstream in(path);
  std::string type;
  int parent = 0;
  while (in >> type) {
    Eigen::Vector3d p, c;
    Eigen::Matrix3d r, i;
    double m;
    in >> p[0] >> p[1] >> p[2];
    for (int k = 0; k < 9; ++k) in >> r(k / 3, k % 3);
    in >> m >> c[0] >> c[1] >> c[2] >> i(0, 0) >> i(0, 1) >> i(0, 2) >> i(1, 1) >> i(1, 2) >> i(2, 2);
    i(1, 0) = i(0, 1);
    i(2, 0) = i(0, 2);
    i(2, 1) = i(1, 2);
    pinocchio::SE3 placement(r, p);
    std::string name = "j" + std::to_string(parent + 1);
    pinocchio::JointIndex id;
    if (type == "RX") id = model.addJoint(parent, pinocchio::JointModelRX(), placement, name);
    else if (type == "RY") id = model.addJoint(parent, pinocchio::JointModelRY(), placement, name);
    else id = model.addJoint(parent, pinocchio::JointModelRZ(), placement, name);
    model.appendBodyToJoint(id, pinocchio::Inertia(m, c, i), pinocchio::SE3::Identity());
    parent = (int)id;
  }
  return model;
}

int main(int argc, char **argv) {
  if (argc < 2) return 2;
  pinocchio::Model model = load(argv[1]);
  model.gravity.linear() << 0, 0, -9.81;
  pinocchio::Data data(model);
  Eigen::VectorXd q(7), v(7), a(7);
  q << 0.1, 0.6, -0.2, -1.2, 0.3, 1.17, 0.4;
  v << 0.5, -0.3, 0.8, 0.1, -0.6, 0.9, -0.2;
  a << 1.0, -2.0, 0.5, 1.5, -0.7, 0.3, 2.0;
  std::printf("pinocchio_rnea_ns %.1f\n", median_ns([&] { pinocchio::rnea(model, data, q, v, a); }));
  std::printf("pinocchio_crba_ns %.1f\n", median_ns([&] { pinocchio::crba(model, data, q); }));
  std::printf("pinocchio_aba_ns %.1f\n", median_ns([&] { pinocchio::aba(model, data, q, v, a); }));
  std::printf("pinocchio_rnea_derivatives_ns %.1f\n",
              median_ns([&] { pinocchio::computeRNEADerivatives(model, data, q, v, a); }));
  std::printf("pinocchio_aba_derivatives_ns %.1f\n",
              median_ns([&] { pinocchio::computeABADerivatives(model, data, q, v, a); }));
  return 0;
}
