#!/usr/bin/env bash
# Pinocchio's C++ (from pip: `pin`, with `cmeel-eigen` for Eigen's headers) against armature's
# dynamics on the same 7-DOF model and state, measured in one run.
# Usage from the repository root: bash bench/dynamics/pinocchio_bench.sh
set -euo pipefail
cd "$(dirname "$0")/../.."
python3 -m pip install -q pin==4.1.0 cmeel-eigen
prefix=$(python3 -c "import cmeel, os; print(os.path.join(os.path.dirname(os.path.dirname(cmeel.__file__)), 'cmeel.prefix'))")
out=$(mktemp -d)
python3 - "$out/model.txt" <<'PY'
import sys
import pinocchio as pin
m = pin.buildModelFromUrdf("crates/kinematics/tests/fixtures/dynamics/arm7.urdf")
with open(sys.argv[1], "w") as f:
    for j in range(1, m.njoints):
        t, y, i = m.joints[j].shortname()[-2:], m.jointPlacements[j], m.inertias[j]
        assert t in ("RX", "RY", "RZ"), t
        I = i.inertia
        f.write(" ".join([t] + [repr(float(x)) for x in list(y.translation) + list(y.rotation.flatten())
                              + [i.mass] + list(i.lever) + [I[0,0], I[0,1], I[0,2], I[1,1], I[1,2], I[2,2]]]) + "\n")
PY
g++ -O3 -march=native -DNDEBUG -std=c++17 -DBOOST_MPL_CFG_NO_PREPROCESSED_HEADERS -DBOOST_MPL_LIMIT_LIST_SIZE=30 -DBOOST_MPL_LIMIT_VECTOR_SIZE=30 -DBOOST_FUSION_INVOKE_MAX_ARITY=12 -DBOOST_FUSION_INVOKE_FUNCTION_OBJECT_MAX_ARITY=12 bench/dynamics/pinocchio_bench.cpp -o "$out/bench" \
    -I"$prefix/include" -I"$prefix/include/eigen3" -L"$prefix/lib" \
    -lpinocchio_default -Wl,-rpath,"$prefix/lib" 2>&1 | grep -v "warning" || true
LD_LIBRARY_PATH="$prefix/lib" "$out/bench" "$out/model.txt"
cargo bench -q -p armature-kinematics --bench dynamics 2>&1 | grep -E "^dynamics|time:"
