// Compiled evaluations of a scene's accelerations and the explicit step loop over them (pinstab._compiled).
#pragma once

#include <memory>
#include <vector>

#include <Python.h>

#include <Eigen/Core>
#include <pinocchio/multibody/data.hpp>
#include <pinocchio/multibody/model.hpp>

namespace pinstab {

using Eigen::VectorXd;
using Eigen::VectorXi;
using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// The pinocchio::Data wrapped by a Python pin.Data of this model (cpp/python_data.cpp); throws
// std::invalid_argument for another object or a Data of another model. The caller keeps the object alive.
pinocchio::Data& python_data(PyObject* object, const pinocchio::Model& model);
// The pinocchio::Model wrapped by a Python pin.Model (throws std::invalid_argument for another object).
const pinocchio::Model& python_model(PyObject* object);
// A Data of the model with every member Pinocchio's constructor sets except the second-order derivative tensors, which
// stay empty (cpp/light_data.cpp): what every pass pinstab runs reads, at O(nv^2) memory instead of O(nv^3).
pinocchio::Data light_data(const pinocchio::Model& model);
// The same as a new Python pin.Data of a Python pin.Model (a new reference).
PyObject* new_python_data(PyObject* model);

// One evaluation a(t, q, v) under applied forces tau (t [s]: prescribed targets read it) for stage `stage` of a step
// (0 at its start; pinstab.system.ConstrainedSystem.acceleration's: a stabilizer may read it); false when its result
// is not to be used (a small pivot, a servo that loses rank or its bounds).
class Kernel {
 public:
  virtual ~Kernel() = default;
  virtual bool acceleration(int stage, double t, const VectorXd& q, const VectorXd& v, const VectorXd& tau,
                            VectorXd& a) = 0;
  virtual int nv() const = 0;
  // The Jacobians of a(t, q, v) under tau at stage `stage`: dadq (nv x nv, against q (+) dq with dq in the tangent space
  // at q) [1/s^2] and dadv (nv x nv) [1/s]; false when not usable. The default: finite differences of acceleration
  // (cpp/jacobian.cpp).
  virtual bool jacobian(int stage, double t, const VectorXd& q, const VectorXd& v, const VectorXd& tau,
                        Eigen::MatrixXd& dadq, Eigen::MatrixXd& dadv);
  // The model whose configuration group the step loop integrates on (pinocchio::integrate, and stage velocities
  // carried to the step's start with dDifference, where its joints are not all of one coordinate), or nullptr: a
  // kernel whose models' joints all are (q (+) dq = q + dq).
  virtual const pinocchio::Model* group() const { return nullptr; }
};

using Mask = Eigen::Array<bool, Eigen::Dynamic, 1>;

// The relative primal residual of a KKT solve (pinstab.solvers.base.primal_residual calls it):
// |G a - rhs| / (|rhs| + |G|_F (|a| + |f| / min diag M)) [-], f the free force, Euclidean norms; a unilateral row
// (unilateral(i) true; an empty mask: none) counts only when violated (G a - rhs < 0). 0 where nothing is missed,
// infinite where the scale is zero and the miss is not.
double primal_residual(const Eigen::MatrixXd& jacobian, const VectorXd& a, const VectorXd& rhs, const VectorXd& force,
                       const VectorXd& mass_diagonal, const Mask& unilateral = Mask());

// The direct solve's test (pinstab.solvers.proxsuite_.direct_solve and CoreKernel call it): the Delassus matrix's
// rows are independent by a margin when the smallest diagonal entry of its Cholesky factor, squared, is at least
// direct_pivot times its largest diagonal entry (`largest`); true for no rows.
bool independent_by_margin(const VectorXd& factor_diagonal, double largest, double direct_pivot);

// A sparse matrix in compressed rows (as scipy's CSR arrays).
struct Csr {
  VectorXi indptr, indices;
  VectorXd data;
  int rows() const { return static_cast<int>(indptr.size()) - 1; }
};

// LAPACK's dgbtf2 / dgbtrs (no transpose) on band storage with kl = ku = band, ldab = 3 band + 1:
// the unblocked LU with partial pivoting that dgbsv runs for a band below its block size.
// Returns LAPACK's info (0: factored; j > 0: U(j, j) is exactly zero).
int banded_solve(Eigen::Ref<Eigen::MatrixXd> ab, int band, Eigen::Ref<VectorXd> b, std::vector<int>& pivots);
// Its two halves: dgbtf2 (the factors overwrite ab; returns info) and dgbtrs (b overwritten by the solution).
int banded_factor(Eigen::Ref<Eigen::MatrixXd> ab, int band, std::vector<int>& pivots);
void banded_substitute(const Eigen::Ref<const Eigen::MatrixXd>& ab, int band, const std::vector<int>& pivots,
                       Eigen::Ref<VectorXd> b);
// residual = b - A x for A in the same band storage (not factored), summed in extended precision (long double):
// the residual of iterative refinement.
void banded_residual(const Eigen::Ref<const Eigen::MatrixXd>& ab, int band, const VectorXd& x, const VectorXd& b,
                     VectorXd& residual);

// The fixed explicit schemes (pinstab.integration.schemes names them; their arithmetic: SchemeStep, cpp/group.hpp).
enum class Scheme { euler = 0, semi_implicit_euler = 1, heun = 2, rk4 = 3 };

// A correction of the state after each step of the fixed-step loop (fixed_steps, cpp/step_loop.hpp; CoreCorrection,
// cpp/projection.hpp: `projection` and `post` on the core path): (q, v) reached at t [s] corrected in place; the
// iterations it took, or -1 where it cannot correct it (the loop stops before that step: the caller takes it).
class Corrector {
 public:
  virtual ~Corrector() = default;
  virtual int correct(double t, VectorXd& q, VectorXd& v) = 0;
};

// The correction of a run's steps: the corrector and each step's iterations (an entry per step asked).
struct Correction {
  Corrector& corrector;
  VectorXi iterations;
};

// Steps of dt from (q, v) at grid step `start` (time start dt): fills rows of qs, vs; returns the steps done (fewer
// than asked when an evaluation was not to be used, or a correction could not be made: the caller takes that step).
// With a correction, each step's end state is corrected (fixed_steps).
int advance(Kernel& kernel, Scheme scheme, const VectorXd& q0, const VectorXd& v0, const VectorXd& tau, double dt,
            long start, int steps, RowMatrix& qs, RowMatrix& vs, Correction* correction = nullptr);

}  // namespace pinstab
