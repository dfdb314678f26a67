#pragma once
// `lambert study`: the accuracy/cost study (see study.cpp and docs/accuracy.md).
#include <string>

namespace lambert::app {

struct StudyOptions {
  std::string out = "study";  // directory; study.csv is written there (atomically)
  bool quick = false;         // the CI subset (< 2 minutes on 2 cores)
  bool quiet = false;
};

int run_study(const StudyOptions& o);

}  // namespace lambert::app
