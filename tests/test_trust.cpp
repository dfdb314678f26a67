// Numbers the user can trust: every failure the run finds is reported and makes `solve` and `formfactors`
// alike exit 3 where the result cannot be trusted; the error bound the summary prints holds against an exact
// answer; --stats has one schema for every command; broken invariants are internal errors, not bad input.
#include <gtest/gtest.h>

#include <cmath>
#include <nlohmann/json.hpp>
#include <sstream>

#include <vtkCellData.h>
#include <vtkDataArray.h>
#include <vtkSmartPointer.h>
#include <vtkUnstructuredGrid.h>
#include <vtkXMLUnstructuredGridReader.h>

#include "cli_util.hpp"
#include "lambert/mesh/shapes.hpp"
#include "lambert/mesh/types.hpp"

namespace {

using lambert::test::Cli;
using lambert::test::run;
using nlohmann::json;
namespace fs = std::filesystem;

json read_json(const std::string& file) {
  std::ifstream in(file);
  return json::parse(in);
}

// Two unit squares 5 cm apart facing each other, one a lamp: the point rule's F = A/(pi r^2) = 127 > 1.
const std::string kCloseSquares =
    "mtllib close.mtl\n"
    "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
    "v 0 0 0.05\nv 1 0 0.05\nv 1 1 0.05\nv 0 1 0.05\n"
    "usemtl floor\nf 1 2 3 4\n"
    "usemtl lamp\nf 5 8 7 6\n";
const std::string kCloseMtl = "newmtl floor\nKd 0.5\nnewmtl lamp\nKd 0\nKe 1\n";

// An icosphere with inward normals, uniform emission 1 and reflectance rho: exact L = 1 / (1 - rho).
std::string icosphere_obj(int K) {
  std::ostringstream s;
  s << "mtllib sphere.mtl\nusemtl glow\n";
  int v = 0;
  for (const auto& tri : lambert::mesh::shapes::icosphere(K, 1.0, true)) {
    for (const auto& p : tri) s << "v " << p.x() << ' ' << p.y() << ' ' << p.z() << '\n';
    s << "f " << v + 1 << ' ' << v + 2 << ' ' << v + 3 << '\n';
    v += 3;
  }
  return s.str();
}

TEST_F(Cli, SolveAndFormfactorsAlikeRefuseFormFactorsOutsideTheUnitInterval) {
  const std::string obj = write("close.obj", kCloseSquares);
  write("close.mtl", kCloseMtl);
  const auto ff = run("formfactors " + obj + " --rule point -o " + path("F.csv") + " --stats " + path("f.json"));
  EXPECT_EQ(ff.status, 3) << ff.output;
  EXPECT_NE(ff.output.find("outside [0, 1]"), std::string::npos) << ff.output;
  const auto so = run("solve " + obj + " --ff-rule point -o " + path("out.vtu") + " --stats " + path("s.json"));
  EXPECT_EQ(so.status, 3) << so.output;
  EXPECT_NE(so.output.find("outside [0, 1]"), std::string::npos) << so.output;
  EXPECT_NE(so.output.find("no output written"), std::string::npos) << so.output;
  for (const char* f : {"F.csv", "f.json", "out.vtu", "s.json"})
    EXPECT_FALSE(fs::exists(path(f))) << f << " was written although the run exited 3";
  // The same scene with the adaptive rule is fine (F = 0.90 each way).
  EXPECT_EQ(run("solve " + obj + " -o " + path("out.vtu") + " --quiet").status, 0);
}

// The summary's bound |dL|/max L <= (rho delta + r)/(1 - rho) must hold against the exact answer. A coarse
// form-factor tolerance (1e-3) makes the form-factor error dominate, so a bound without its form-factor term
// fails here (seen). The bound is conservative (the a-priori model's constants are 4x the worst measured
// ratio), so it is far above the error; what this test guards is that it is never below it.
TEST_F(Cli, PrintedErrorBoundHoldsOnTheEmittingSphere) {
  const std::string obj = write("sphere.obj", icosphere_obj(2));
  for (double rho : {0.5, 0.9, 0.99}) {
    write("sphere.mtl", "newmtl glow\nKd " + std::to_string(rho) + "\nKe 1\n");
    const auto r = run("solve " + obj + " --ff-tolerance 1e-3 -o " + path("s.vtu") + " --stats " + path("s.json"));
    ASSERT_EQ(r.status, 0) << r.output;
    const json st = read_json(path("s.json"));
    ASSERT_TRUE(st["error_bound"]["exists"].get<bool>()) << st.dump(2);
    const double bound = st["error_bound"]["relative_radiance"].get<double>();
    auto reader = vtkSmartPointer<vtkXMLUnstructuredGridReader>::New();
    reader->SetFileName(path("s.vtu").c_str());
    reader->Update();
    vtkDataArray* L = reader->GetOutput()->GetCellData()->GetArray("radiance");
    ASSERT_NE(L, nullptr);
    const double exact = 1 / (1 - rho);
    double worst = 0, max_L = 0;
    vtkIdType worst_cell = -1;
    for (vtkIdType c = 0; c < L->GetNumberOfTuples(); ++c) {
      max_L = std::max(max_L, L->GetComponent(c, 0));
      if (std::abs(L->GetComponent(c, 0) - exact) > worst) worst = std::abs(L->GetComponent(c, 0) - exact), worst_cell = c;
    }
    std::printf("rho %.2f: max |L - exact| / max L = %.3e, printed bound %.3e (cell %lld)\n", rho, worst / max_L, bound,
                (long long)worst_cell);
    EXPECT_LE(worst / max_L, bound) << "rho " << rho << " cell " << worst_cell << "\n" << r.output;
    EXPECT_NE(r.output.find("error bound"), std::string::npos) << r.output;
  }
}

TEST_F(Cli, StatsHaveOneSchemaForSolveAdaptiveSolveAndFormfactors) {
  const std::string obj = write("close.obj", kCloseSquares);
  write("close.mtl", kCloseMtl);
  ASSERT_EQ(run("solve " + obj + " -o " + path("a.vtu") + " --stats " + path("a.json") + " --quiet").status, 0);
  ASSERT_EQ(run("solve " + obj + " -o " + path("b.vtu") + " --adaptive-budget 40 --stats " + path("b.json") + " --quiet")
                .status,
            0);
  ASSERT_EQ(run("formfactors " + obj + " -o " + path("c.csv") + " --stats " + path("c.json") + " --quiet").status, 0);
  const json a = read_json(path("a.json")), b = read_json(path("b.json")), c = read_json(path("c.json"));
  for (const json* j : {&a, &b, &c}) {
    for (const char* key : {"version", "command", "scene", "patches", "input_faces", "phases", "warnings", "findings",
                            "form_factors", "iterations", "residual"})
      EXPECT_TRUE(j->contains(key)) << key << " missing in\n" << j->dump(2);
    for (const char* key : {"rule", "tolerance", "pairs_total", "row_sum", "rays_cast", "pairs_over_tolerance"})
      EXPECT_TRUE((*j)["form_factors"].contains(key)) << key << " missing in form_factors of\n" << j->dump(2);
  }
  for (const json* j : {&a, &b})
    for (const char* key : {"method", "channels", "energy", "error_bound", "converged"})
      EXPECT_TRUE(j->contains(key)) << key << " missing in\n" << j->dump(2);
  ASSERT_TRUE(b.contains("adaptive"));
  for (const auto& round : b["adaptive"]["rounds"]) {
    EXPECT_TRUE(round.contains("form_factors")) << round.dump(2);
    EXPECT_TRUE(round["solve_converged"].get<bool>()) << round.dump(2);
  }
  EXPECT_EQ(a["command"], "solve");
  EXPECT_EQ(c["command"], "formfactors");
}

// Form factors need no emitter: `formfactors` does not warn that "the solution will be zero" (it solves
// nothing); `solve` does.
TEST_F(Cli, NoEmitterWarningOnlyWhereSomethingIsSolved) {
  const std::string obj = write("close.obj", kCloseSquares);
  write("close.mtl", "newmtl floor\nKd 0.5\nnewmtl lamp\nKd 0.5\n");
  const auto ff = run("formfactors " + obj + " -o " + path("F.csv"));
  EXPECT_EQ(ff.status, 0) << ff.output;
  EXPECT_EQ(ff.output.find("no emitter"), std::string::npos) << ff.output;
  const auto so = run("solve " + obj + " -o " + path("s.vtu"));
  EXPECT_EQ(so.status, 0) << so.output;
  EXPECT_NE(so.output.find("no emitter"), std::string::npos) << so.output;
}

TEST_F(Cli, AdaptiveRoundWhoseSolveDoesNotConvergeExitsThree) {
  const std::string obj = write("close.obj", kCloseSquares);
  write("close.mtl", "newmtl floor\nKd 0.9\nnewmtl lamp\nKd 0.9\nKe 1\n");
  const auto r = run("solve " + obj + " -o " + path("a.vtu") + " --adaptive-budget 40 --method jacobi --max-iterations 2");
  EXPECT_EQ(r.status, 3) << r.output;
  EXPECT_NE(r.output.find("did not reach the tolerance"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(path("a.vtu")));
}

TEST(Invariant, CheckFailureIsAnInternalErrorNamingConditionPlaceAndMessage) {
  try {
    LAMBERT_CHECK(1 + 1 == 3, "arithmetic");
    FAIL() << "LAMBERT_CHECK did not throw";
  } catch (const lambert::InternalError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("1 + 1 == 3"), std::string::npos) << what;
    EXPECT_NE(what.find("test_trust.cpp"), std::string::npos) << what;
    EXPECT_NE(what.find("arithmetic"), std::string::npos) << what;
  }
  EXPECT_NO_THROW(LAMBERT_CHECK(1 + 1 == 2, "arithmetic"));
}

}  // namespace
