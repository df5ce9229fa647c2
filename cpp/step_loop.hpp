// The fixed-step loop of the compiled runs (advance: the schemes; advance_tableau: a Runge-Kutta tableau), written
// once over the step it takes.
#pragma once

#include "kernels.hpp"

namespace pinstab {

// Steps of dt from (q, v) at grid step `start` (time start dt, as Python's k * dt), each by take(t, q, v) (false:
// its evaluation is not to be used, q and v unchanged), then with a correction its end state corrected at the step's
// end, Python's grid time (k + 1) dt (its iterations in correction->iterations): fills rows of qs, vs; returns the
// steps done (fewer when a step's evaluation is not to be used or its correction cannot be made).
template <class Take>
int fixed_steps(Take&& take, VectorXd q, VectorXd v, double dt, long start, int steps, RowMatrix& qs, RowMatrix& vs,
                Correction* correction = nullptr) {
  for (int k = 0; k < steps; ++k) {
    if (!take(static_cast<double>(start + k) * dt, q, v)) return k;
    if (correction != nullptr) {
      const int iterations = correction->corrector.correct(static_cast<double>(start + k + 1) * dt, q, v);
      if (iterations < 0) return k;
      correction->iterations(k) = iterations;
    }
    qs.row(k) = q.transpose();
    vs.row(k) = v.transpose();
  }
  return steps;
}

}  // namespace pinstab
