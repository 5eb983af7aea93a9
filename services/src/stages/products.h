#pragma once
// What one stage hands to the later ones (StageContext::products), where it is not a solver's own
// result type (static optimization hands on its StaticOptimizationResult).
#include <Eigen/Core>
#include <vector>

#include "cpgait/capture/storage.h"
#include "cpgait/cpg/cpg_fit.h"

namespace cpgait::services {

struct IkProduct {
  Storage coordinates;  // OpenSim's table (degrees), the input of ID and SO
  Eigen::MatrixXd q;    // frames x coordinates, SI
  std::vector<double> time_s;
};

struct FittedCpg {
  CpgModel model;
  std::vector<double> heel_strikes_s;  // of the foot whose cycles it was fitted to
};

}  // namespace cpgait::services
