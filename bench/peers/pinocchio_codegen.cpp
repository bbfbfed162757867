// Pinocchio's code generation (CppADCodeGen) for one robot: each variant's straight-line C,
// saved as CppADCodeGen writes them (bench/peers/pinocchio_cg.py runs this program;
// bench/peers/harness.py compiles and times the C).
//
//   pinocchio_codegen URDF OUTDIR [VARIANT ...]
//
// The URDF is the model robotgen builds (the driver writes a copy with robotgen's locked
// joints fixed). Each variant VARIANT is saved under OUTDIR/VARIANT/ as CppADCodeGen's sources;
// the function the bench calls is pcg_VARIANT_forward_zero (and, for the variants whose Jacobian
// CppAD differentiates, pcg_VARIANT_jacobian) with the signature
//   void f(double const *const *in, double *const *out, struct LangCAtomicFun atomic)
// in[0] = [q, v, a or tau] and out[0] the outputs listed in VARIANTS below.
//
// Pinocchio's own classes (pinocchio/codegen/cppadcg-algo.hpp): CodeGenCRBA, CodeGenRNEA,
// CodeGenABA, CodeGenMinv, CodeGenRNEADerivatives, CodeGenABADerivatives; CodeGenRNEA's and
// CodeGenABA's Jacobians by CppAD (forward or reverse mode, as CppAD chooses). Traced here:
// CRBA + Cholesky (M = U D U^T) for forward dynamics and M^-1, the RNEA derivatives with only
// the two matrices robotgen returns, and forward dynamics' derivatives as
// ddq_dq = -M^-1 dtau_dq, ddq_dv = -M^-1 dtau_dv at ddq (Carpentier and Mansard 2018, eq 16).
#include <pinocchio/codegen/cppadcg-algo.hpp>
#include <pinocchio/algorithm/cholesky.hpp>
#include <pinocchio/parsers/urdf.hpp>

#include <cstdio>
#include <functional>
#include <map>
#include <memory>

namespace
{
  using Base = pinocchio::CodeGenBase<double>;
  using Model = Base::Model;

  // A Pinocchio code generator whose sources are saved rather than compiled into a library.
  template<class Generator>
  struct Saved : Generator
  {
    explicit Saved(const Model & model, const std::string & name)
    : Generator(model, name, name)
    {
    }

    void save(const std::string & dir)
    {
      this->initLib();
      CppAD::cg::SaveFilesModelLibraryProcessor<double> saver(*this->libcgen_ptr);
      saver.saveSourcesTo(dir);
    }
  };

  // The traced variants: Y = f(X) recorded by CppAD on Pinocchio's algorithms, forward code only.
  struct Traced : Base
  {
    using ADScalar = Base::ADScalar;
    using ADVector = Base::ADVectorXs;
    using ADRowMatrix = Eigen::Matrix<ADScalar, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
    using Body = std::function<void(Traced &, const ADVector & q, const ADVector & v, const ADVector & u)>;

    Traced(const Model & model, const std::string & name, Eigen::Index inputs, Eigen::Index outputs, Body body)
    : Base(model, inputs, outputs, name, name)
    , body(std::move(body))
    {
      build_jacobian = false;
    }

    void buildMap() override
    {
      CppAD::Independent(ad_X);
      const Eigen::Index nq = ad_model.nq, nv = ad_model.nv;
      ADVector q = ad_X.head(nq);
      ADVector v = ad_X.size() > nq ? ADVector(ad_X.segment(nq, nv)) : ADVector::Zero(nv);
      ADVector u = ad_X.size() > nq ? ADVector(ad_X.segment(nq + nv, nv)) : ADVector::Zero(nv);
      body(*this, q, v, u);
      ad_fun.Dependent(ad_X, ad_Y);
      ad_fun.optimize("no_compare_op");
    }

    void save(const std::string & dir)
    {
      initLib();
      CppAD::cg::SaveFilesModelLibraryProcessor<double> saver(*libcgen_ptr);
      saver.saveSourcesTo(dir);
    }

    // M by CRBA (upper triangle, Pinocchio's convention), factored M = U D U^T in ad_data.
    void factor(const ADVector & q)
    {
      pinocchio::crba(ad_model, ad_data, q, pinocchio::Convention::WORLD);
      pinocchio::cholesky::decompose(ad_model, ad_data);
    }

    // ddq = M^-1 (u - b(q, v)), b = rnea(q, v, 0): Newton-Euler's bias forces.
    ADVector accelerations(const ADVector & q, const ADVector & v, const ADVector & u)
    {
      ADVector ddq = u - pinocchio::nonLinearEffects(ad_model, ad_data, q, v);
      factor(q);
      pinocchio::cholesky::solve(ad_model, ad_data, ddq);
      return ddq;
    }

    void put(Eigen::Index & at, const ADRowMatrix & m)
    {
      Eigen::Map<ADRowMatrix>(ad_Y.data() + at, m.rows(), m.cols()) = m;
      at += m.size();
    }

    void put_upper(Eigen::Index & at, const ADRowMatrix & m)
    {
      for (Eigen::Index i = 0; i < m.rows(); ++i)
        for (Eigen::Index j = i; j < m.cols(); ++j)
          ad_Y[at++] = m(i, j);
    }

    Body body;
    using Base::ad_data;
    using Base::ad_model;
    using Base::ad_Y;
  };

  using Variant = std::function<void(const Model &, const std::string & name, const std::string & dir)>;

  template<class Generator>
  Variant stock()
  {
    return [](const Model & model, const std::string & name, const std::string & dir) {
      Saved<Generator>(model, name).save(dir);
    };
  }

  // A traced variant: inputs q (and v, u when inputs_per_nv is 2), OUTPUTS values.
  Variant traced(Eigen::Index inputs_per_nv, Eigen::Index outputs, Traced::Body body)
  {
    return [=](const Model & model, const std::string & name, const std::string & dir) {
      Traced(model, name, model.nq + inputs_per_nv * model.nv, outputs, body).save(dir);
    };
  }

  std::map<std::string, Variant> variants(const Model & model)
  {
    using V = Traced::ADVector;
    const Eigen::Index nv = model.nv, upper = nv * (nv + 1) / 2;
    std::map<std::string, Variant> out;
    // out[0]: M's upper triangle, row by row
    out["crba"] = stock<pinocchio::CodeGenCRBA<double>>();
    // out[0]: tau (and, CppAD's Jacobian, [dtau_dq dtau_dv dtau_da] row-major)
    out["rnea"] = stock<pinocchio::CodeGenRNEA<double>>();
    // out[0]: ddq (and, CppAD's Jacobian, [dddq_dq dddq_dv dddq_dtau] row-major)
    out["aba"] = stock<pinocchio::CodeGenABA<double>>();
    // out[0]: M^-1's upper triangle, row by row
    out["minv"] = stock<pinocchio::CodeGenMinv<double>>();
    // out[0]: dtau_dq, dtau_dv, dtau_da (= M), each row-major
    out["rnea_derivatives"] = stock<pinocchio::CodeGenRNEADerivatives<double>>();
    // out[0]: ddq_dq, ddq_dv, ddq_dtau (= M^-1), each row-major
    out["aba_derivatives"] = stock<pinocchio::CodeGenABADerivatives<double>>();
    // out[0]: ddq by CRBA, Cholesky and the bias forces
    out["crba_cholesky_fd"] = traced(2, nv, [](Traced & t, const V & q, const V & v, const V & u) {
      t.ad_Y = t.accelerations(q, v, u);
    });
    // out[0]: M^-1's upper triangle, from the Cholesky factors
    out["crba_cholesky_minv"] = traced(0, upper, [](Traced & t, const V & q, const V &, const V &) {
      t.factor(q);
      Traced::ADRowMatrix minv(t.ad_model.nv, t.ad_model.nv);
      pinocchio::cholesky::computeMinv(t.ad_model, t.ad_data, minv);
      Eigen::Index at = 0;
      t.put_upper(at, minv);
    });
    // out[0]: dtau_dq, dtau_dv row-major: what robotgen's inverse_dynamics_derivatives returns
    out["rnea_derivatives_dq_dv"] = traced(2, 2 * nv * nv, [](Traced & t, const V & q, const V & v, const V & u) {
      const Eigen::Index n = t.ad_model.nv;
      Traced::ADRowMatrix dq = Traced::ADRowMatrix::Zero(n, n), dv = dq, da = dq;
      pinocchio::computeRNEADerivatives(t.ad_model, t.ad_data, q, v, u, dq, dv, da);
      Eigen::Index at = 0;
      t.put(at, dq);
      t.put(at, dv);
    });
    // out[0]: ddq_dq, ddq_dv, M^-1 row-major: RNEA's derivatives at ddq, times -M^-1
    out["crba_cholesky_fd_derivatives"] = traced(2, 3 * nv * nv, [](Traced & t, const V & q, const V & v, const V & u) {
      const Eigen::Index n = t.ad_model.nv;
      Traced::ADVector ddq = t.accelerations(q, v, u);
      Traced::ADRowMatrix minv(n, n);
      pinocchio::cholesky::computeMinv(t.ad_model, t.ad_data, minv);
      Traced::ADRowMatrix dq = Traced::ADRowMatrix::Zero(n, n), dv = dq, da = dq;
      pinocchio::computeRNEADerivatives(t.ad_model, t.ad_data, q, v, ddq, dq, dv, da);
      Eigen::Index at = 0;
      t.put(at, -minv * dq);
      t.put(at, -minv * dv);
      t.put(at, minv);
    });
    return out;
  }
} // namespace

int main(int argc, char ** argv)
{
  if (argc < 3)
  {
    std::fprintf(stderr, "usage: %s URDF OUTDIR [VARIANT ...]\n", argv[0]);
    return 2;
  }
  Model model;
  pinocchio::urdf::buildModel(argv[1], model);
  model.name = "robot";
  const auto all = variants(model);
  std::vector<std::string> chosen(argv + 3, argv + argc);
  if (chosen.empty())
    for (const auto & kv : all)
      chosen.push_back(kv.first);
  for (const auto & name : chosen)
  {
    const auto it = all.find(name);
    if (it == all.end())
    {
      std::fprintf(stderr, "pinocchio_codegen: no variant %s\n", name.c_str());
      return 2;
    }
    it->second(model, "pcg_" + name, std::string(argv[2]) + "/" + name);
    std::printf("%s\n", name.c_str());
    std::fflush(stdout);
  }
  return 0;
}
