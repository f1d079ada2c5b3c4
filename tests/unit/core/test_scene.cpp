// Scene parsing and validation: every kind of bad input is an InputError naming file, line and
// key, with a suggestion where one makes sense.
#include <gtest/gtest.h>

#include "core/Error.hpp"
#include "core/Scene.hpp"

namespace gw = grainwave;

namespace {

gw::SceneSchema test_schema() {
  gw::SceneSchema s;
  auto& run = s.section("run", "run control");
  run.real("t_end", std::nullopt, "end time").above(0);
  run.real("dt", 0.0, "step").at_least(0);
  run.integer("max_steps", 0, "limit").at_least(0);
  auto& p = s.section("particles", "particles");
  p.text("placement", "random", "how").one_of({"random", "fcc"});
  p.reals("gravity", std::vector<double>{0, 0, 0}, "g").of_length(3);
  p.flag("collisions", true, "collide");
  auto& e = s.section("particle", "one particle", true);
  e.reals("position", std::nullopt, "x").of_length(3);
  return s;
}

gw::InputError error_of(const std::string& text, std::vector<std::string> overrides = {}) {
  try {
    gw::Scene::parse(text, "scene.toml", overrides, test_schema());
  } catch (const gw::InputError& e) {
    return e;
  }
  ADD_FAILURE() << "no InputError for:\n" << text;
  return gw::InputError({}, "", "");
}

}  // namespace

TEST(Scene, ResolvesDefaultsAndTypes) {
  const auto scene = gw::Scene::parse("[run]\nt_end = 2\n[particles]\nplacement = \"fcc\"\n",
                                      "cases/x.toml", {}, test_schema());
  EXPECT_EQ(scene.name(), "x");
  EXPECT_DOUBLE_EQ(scene.section("run").real("t_end"), 2.0);  // integer accepted as real
  EXPECT_DOUBLE_EQ(scene.section("run").real("dt"), 0.0);
  EXPECT_FALSE(scene.section("run").is_explicit("dt"));
  EXPECT_TRUE(scene.section("run").is_explicit("t_end"));
  EXPECT_EQ(scene.section("particles").text("placement"), "fcc");
  EXPECT_EQ(scene.section("particles").reals("gravity").size(), 3u);
  EXPECT_TRUE(scene.has("particles"));
  EXPECT_FALSE(scene.has("particle"));
  EXPECT_EQ(scene.sha256().size(), 64u);
}

TEST(Scene, UnknownKeyNamesLineAndSuggests) {
  const auto e = error_of("[run]\nt_end = 1\ntned = 3\n");
  EXPECT_EQ(e.where().file, "scene.toml");
  EXPECT_EQ(e.where().line, 3);
  EXPECT_EQ(e.key(), "run.tned");
  EXPECT_NE(e.hint().find("run.t_end"), std::string::npos) << e.what();
}

TEST(Scene, UnknownKeySuggestsOtherSection) {
  const auto e = error_of("[run]\nt_end = 1\nplacment = \"fcc\"\n");
  EXPECT_NE(e.hint().find("particles.placement"), std::string::npos) << e.what();
}

TEST(Scene, UnknownSection) {
  const auto e = error_of("[run]\nt_end = 1\n[particels]\nplacement = \"fcc\"\n");
  EXPECT_EQ(e.key(), "particels");
  EXPECT_NE(e.hint().find("[particles]"), std::string::npos) << e.what();
}

TEST(Scene, WrongType) {
  const auto e = error_of("[run]\nt_end = \"soon\"\n");
  EXPECT_EQ(e.where().line, 2);
  EXPECT_EQ(e.key(), "run.t_end");
  EXPECT_NE(e.message().find("expected real, got string"), std::string::npos) << e.what();
}

TEST(Scene, OutOfRange) {
  const auto e = error_of("[run]\nt_end = -1.0\n");
  EXPECT_EQ(e.key(), "run.t_end");
  EXPECT_NE(e.message().find("out of range (0, inf)"), std::string::npos) << e.what();
}

TEST(Scene, WrongArrayLengthAndBadChoice) {
  EXPECT_NE(error_of("[run]\nt_end = 1\n[particles]\ngravity = [0, 1]\n").message().find(
                "expected 3 values"),
            std::string::npos);
  const auto e = error_of("[run]\nt_end = 1\n[particles]\nplacement = \"fccc\"\n");
  EXPECT_NE(e.hint().find("did you mean 'fcc'"), std::string::npos) << e.what();
}

TEST(Scene, MissingRequiredKeyNamesSection) {
  const auto e = error_of("\n[run]\ndt = 0.1\n");
  EXPECT_EQ(e.key(), "run.t_end");
  EXPECT_EQ(e.where().line, 2);
  EXPECT_NE(e.message().find("required"), std::string::npos);
}

TEST(Scene, MalformedToml) {
  const auto e = error_of("[run]\nt_end = 1\ndt = = 2\n");
  EXPECT_EQ(e.where().line, 3);
  EXPECT_NE(e.message().find("malformed TOML"), std::string::npos) << e.what();
}

TEST(Scene, UnreadableFile) {
  try {
    gw::Scene::load("/nonexistent/scene.toml", {}, test_schema());
    FAIL() << "expected InputError";
  } catch (const gw::InputError& e) {
    EXPECT_EQ(e.where().file, "/nonexistent/scene.toml");
    EXPECT_NE(e.message().find("cannot read"), std::string::npos);
  }
}

TEST(Scene, OverridesApplyAndAreValidated) {
  const auto scene = gw::Scene::parse("[run]\nt_end = 1\n", "s.toml",
                                      {"run.t_end=5", "particles.placement=fcc"}, test_schema());
  EXPECT_DOUBLE_EQ(scene.section("run").real("t_end"), 5.0);
  EXPECT_EQ(scene.section("particles").text("placement"), "fcc");  // bare word -> string
  const auto e = error_of("[run]\nt_end = 1\n", {"run.max_steps=-3"});
  EXPECT_EQ(e.where().file, "--set run.max_steps=-3");
  const auto u = error_of("[run]\nt_end = 1\n", {"run.tend=3"});
  EXPECT_NE(u.hint().find("run.t_end"), std::string::npos);
}

TEST(Scene, RepeatedSections) {
  const auto scene = gw::Scene::parse(
      "[run]\nt_end = 1\n[[particle]]\nposition = [0,0,0]\n[[particle]]\nposition = [1,0,0]\n",
      "s.toml", {"particle.1.position=[2.0, 0, 0]"}, test_schema());
  ASSERT_EQ(scene.entries("particle").size(), 2u);
  EXPECT_DOUBLE_EQ(scene.entries("particle")[1].reals("position")[0], 2.0);
  const auto e = error_of("[run]\nt_end = 1\n[[particle]]\nposition = [0,0]\n");
  EXPECT_EQ(e.key(), "particle.0.position");
  EXPECT_EQ(e.where().line, 4);
}

TEST(Scene, SemanticErrorsPointAtTheKey) {
  const auto scene = gw::Scene::parse("[run]\nt_end = 1\n\ndt = 0.5\n", "s.toml", {}, test_schema());
  try {
    scene.section("run").fail("dt", "too large");
    FAIL();
  } catch (const gw::InputError& e) {
    EXPECT_EQ(std::string(e.what()), "s.toml:4: key 'run.dt': too large");
  }
}

TEST(Parameters, EditDistanceAndSuggestions) {
  EXPECT_EQ(gw::edit_distance("t_end", "t_end"), 0u);
  EXPECT_EQ(gw::edit_distance("tned", "tend"), 1u);  // transposition
  EXPECT_EQ(gw::edit_distance("kitten", "sitting"), 3u);
  EXPECT_EQ(gw::closest_match("palcement", {"placement", "count"}).value(), "placement");
  EXPECT_FALSE(gw::closest_match("zzzzzz", {"placement", "count"}).has_value());
}

TEST(Parameters, ReferenceMarkdownListsEveryKey) {
  const auto md = test_schema().reference_markdown();
  EXPECT_NE(md.find("## [run]"), std::string::npos);
  EXPECT_NE(md.find("## [[particle]]"), std::string::npos);
  EXPECT_NE(md.find("| `t_end` | real | **required** | (0, inf) |"), std::string::npos) << md;
}
