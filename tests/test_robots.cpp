// The shipped robots found at run time (robots.hpp: $STEPCAL_ROBOTS_DIR, then beside the
// executable), and what a command reads from a URDF when it is not told: the chain's ends and
// the joints' effort limits.
#include <gtest/gtest.h>
#include <stdlib.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "stepcal/common/error.hpp"
#include "stepcal/common/robots.hpp"
#include "stepcal/common/urdf.hpp"
#include "support/files.hpp"
#include "support/input_error.hpp"

namespace stepcal {
namespace {

namespace fs = std::filesystem;

const std::string kSourceRobots = STEPCAL_ROBOTS_DIR;

/// Expects call() to throw an InputError whose message holds every one of parts.
template <typename Call>
void expectRefused(Call&& call, const std::vector<std::string>& parts) {
  const std::string what = test::refusalOf(std::forward<Call>(call)).what;
  for (const std::string& part : parts) EXPECT_NE(what.find(part), std::string::npos) << what;
}

/// Sets an environment variable for one scope, restoring the previous value.
class ScopedEnv {
 public:
  ScopedEnv(const char* name, const std::string& value) : name_(name) {
    if (const char* old = std::getenv(name)) old_ = old;
    ::setenv(name, value.c_str(), 1);
  }
  ~ScopedEnv() {
    if (old_.empty()) {
      ::unsetenv(name_);
    } else {
      ::setenv(name_, old_.c_str(), 1);
    }
  }

 private:
  const char* name_;
  std::string old_;
};

TEST(Robots, ShippedRobotsAreFoundBesideTheExecutable) {
  ::unsetenv(kRobotsDirEnv);
  const fs::path beside = fs::read_symlink("/proc/self/exe").parent_path().parent_path() /
                          "share" / "stepcal" / "robots";
  ASSERT_EQ(robotSearchFolders(), std::vector<std::string>{beside.string()});
  const std::vector<std::string> names = shippedRobots();
  EXPECT_EQ(names, (std::vector<std::string>{"irb4400", "ur10"}));
  for (const std::string& name : names) {
    const std::string path = robotDescriptionPath(name);
    EXPECT_EQ(path, (beside / (name + ".urdf")).string());
    // The build's copy is the source's.
    EXPECT_EQ(readTextFile(path), readTextFile(kSourceRobots + "/" + name + ".urdf")) << name;
  }
}

TEST(Robots, TheEnvironmentsFolderComesFirst) {
  const test::TempDir dir;
  std::ofstream(dir.path() / "ur10.urdf") << readTextFile(kSourceRobots + "/irb4400.urdf");
  std::ofstream(dir.path() / "my_arm.urdf") << readTextFile(kSourceRobots + "/ur10.urdf");
  const ScopedEnv env(kRobotsDirEnv, dir.path().string());
  EXPECT_EQ(robotSearchFolders().front(), dir.path().string());
  EXPECT_EQ(robotDescriptionPath("my_arm"), (dir.path() / "my_arm.urdf").string());
  // A name in both folders: the environment's.
  EXPECT_EQ(robotDescriptionPath("ur10"), (dir.path() / "ur10.urdf").string());
  EXPECT_EQ(robotDescriptionPath("irb4400"),
            (fs::read_symlink("/proc/self/exe").parent_path().parent_path() / "share" / "stepcal" /
             "robots" / "irb4400.urdf")
                .string());
  EXPECT_EQ(shippedRobots(), (std::vector<std::string>{"irb4400", "my_arm", "ur10"}));
}

TEST(Robots, PathsAndUnknownNamesAreRefusedWithWhatWasSearched) {
  ::unsetenv(kRobotsDirEnv);
  EXPECT_TRUE(isRobotPath("robots/ur10.urdf"));
  EXPECT_TRUE(isRobotPath("arm.urdf"));
  EXPECT_TRUE(isRobotPath("/abs/arm"));
  EXPECT_FALSE(isRobotPath("ur10"));
  const std::string source_ur10 = kSourceRobots + "/ur10.urdf";
  EXPECT_EQ(robotDescriptionPath(source_ur10), source_ur10);  // a file as given
  expectRefused([] { robotDescriptionPath("ur5"); },
                         {"--robot 'ur5': no shipped robot of that name in ",
                          "share/stepcal/robots; expected one of irb4400, ur10 or a URDF file",
                          "STEPCAL_ROBOTS_DIR"});
  expectRefused([] { robotDescriptionPath("robots/ur5.urdf"); },
                         {"--robot 'robots/ur5.urdf': no such file; expected a URDF file",
                          "(irb4400, ur10)"});
  expectRefused([] { robotDescriptionPath(""); }, {"--robot is empty"});
  const test::TempDir dir;
  expectRefused([&] { robotDescriptionPath(dir.path().string()); },
                         {"': is a folder; expected a URDF file"});  // named as a folder
}

TEST(Urdf, ChainEndsAreTheRootAndTheEndOfTheArm) {
  const std::string ur10 = readTextFile(kSourceRobots + "/ur10.urdf");
  const std::string irb = readTextFile(kSourceRobots + "/irb4400.urdf");
  const UrdfChainEnds ur10_ends = urdfChainEnds(ur10, "ur10.urdf");
  EXPECT_EQ(ur10_ends.base_link, "base_link");
  EXPECT_EQ(ur10_ends.tip_link, "tool0");
  const UrdfChainEnds irb_ends = urdfChainEnds(irb, "irb4400.urdf");
  EXPECT_EQ(irb_ends.base_link, "base_link");
  EXPECT_EQ(irb_ends.tip_link, "tmac");  // past ft_sensor, on the same fixed branch
  EXPECT_EQ(urdfRobotName(irb, "irb4400.urdf"), "abb_irb4400_60");
  EXPECT_TRUE(urdfHasLink(irb, "ft_sensor", "irb4400.urdf"));
  EXPECT_FALSE(urdfHasLink(ur10, "ft_sensor", "ur10.urdf"));

  // A second leaf after the last axis (a camera on the flange): which one is tracked is the
  // user's to say.
  std::string branched = ur10;
  branched.insert(branched.rfind("</robot>"),
                  "<link name=\"camera\"/><joint name=\"wrist_3-camera\" type=\"fixed\"><parent "
                  "link=\"wrist_3_link\"/><child link=\"camera\"/></joint>\n");
  expectRefused([&] { urdfChainEnds(branched, "branched.urdf"); },
                         {"branched.urdf", "the links camera, tool0 all end a chain of 6 revolute "
                                           "joints below 'base_link'",
                          "--tip-link"});
  // A leaf nearer the base (a cable guide on link 2) is no end of the arm.
  std::string side = ur10;
  side.insert(side.rfind("</robot>"),
              "<link name=\"guide\"/><joint name=\"guide\" type=\"fixed\"><parent "
              "link=\"upper_arm_link\"/><child link=\"guide\"/></joint>\n");
  EXPECT_EQ(urdfChainEnds(side, "side.urdf").tip_link, "tool0");
  expectRefused(
      [] {
        urdfChainEnds("<robot name=\"r\"><link name=\"a\"/><link name=\"b\"/><joint name=\"j\" "
                      "type=\"fixed\"><parent link=\"a\"/><child link=\"b\"/></joint></robot>",
                      "fixed.urdf");
      },
      {"fixed.urdf", "no revolute joint below the root link 'a'; expected a serial arm"});
}

TEST(Urdf, EffortLimitsOfTheChainsJoints) {
  const std::string ur10 = readTextFile(kSourceRobots + "/ur10.urdf");
  EXPECT_EQ(jointEffortLimits(ur10, "base_link", "tool0", "ur10.urdf"),
            (std::vector<double>{330, 330, 150, 54, 54, 54}));
  // effort="0" in the IRB4400's description: none given.
  EXPECT_EQ(jointEffortLimits(readTextFile(kSourceRobots + "/irb4400.urdf"), "base_link", "tmac",
                              "irb4400.urdf"),
            std::vector<double>(6, 0.0));
  expectRefused([&] { jointEffortLimits(ur10, "base_link", "tmac", "ur10.urdf"); },
                         {"ur10.urdf", "tip_link 'tmac' is not a link"});
}

}  // namespace
}  // namespace stepcal
