#pragma once
// Test helpers for running dem_offline as a user does: a unique temporary directory per test,
// sequences built from the bundled KITTI sample with changes, and the outcome of a run.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <string>
#include <vector>

namespace sgd_test {

namespace fs = std::filesystem;

inline const std::string kSample = std::string(SGD_SOURCE_DIR) + "/data/kitti_seq06_sample";

inline std::string slurp(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  std::ostringstream os;
  os << f.rdbuf();
  return os.str();
}

inline void spit(const std::string& path, const std::string& text) { std::ofstream(path, std::ios::binary) << text; }

inline int lineCount(const std::string& s) {
  int n = 0;
  for (char c : s) n += c == '\n';
  return n;
}

/// A fresh directory per test (named after the test and the process), removed at the end.
class TempDirTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() /
           ("sgd_" + std::to_string(::getpid()) + "_" + info->test_suite_name() + "_" + info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    if (!HasFailure()) fs::remove_all(dir_);  // kept for inspection when a test fails
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  struct Outcome {
    int status = -1;
    std::string err, out;
  };
  /// Runs dem_offline with `args` (a shell fragment), capturing stdout and stderr.
  Outcome run(const std::string& args) const {
    const std::string err_file = path("stderr.txt"), out_file = path("stdout.txt");
    const std::string cmd = std::string(DEM_OFFLINE) + " " + args + " >" + out_file + " 2>" + err_file;
    const int raw = std::system(cmd.c_str());
    Outcome r;
    r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
    r.err = slurp(err_file);
    r.out = slurp(out_file);
    return r;
  }

  /// A copy of the first `frames` frames of the bundled sample in dir/<name> (image_l, image_r,
  /// calib.txt, times.txt); `change(frame, side, image)` may edit each image before it is written
  /// and returns the file name to write it as ("" = the usual 000000.png).
  using Change = std::function<std::string(int frame, char side, cv::Mat* image)>;
  std::string makeSequence(const std::string& name, int frames, const Change& change = nullptr) const {
    const fs::path d = dir_ / name;
    fs::create_directories(d / "image_l");
    fs::create_directories(d / "image_r");
    fs::copy_file(kSample + "/calib.txt", d / "calib.txt");
    fs::copy_file(kSample + "/times.txt", d / "times.txt");
    for (int i = 0; i < frames; ++i) {
      for (char side : {'l', 'r'}) {
        char file[32];
        std::snprintf(file, sizeof(file), "%06d.png", i);
        cv::Mat image = cv::imread(kSample + "/image_" + side + "/" + file, cv::IMREAD_UNCHANGED);
        std::string out_name = change ? change(i, side, &image) : std::string();
        if (out_name.empty()) out_name = file;
        if (!image.empty()) {
          EXPECT_TRUE(cv::imwrite((d / (std::string("image_") + side) / out_name).string(), image)) << out_name;
        }
      }
    }
    return d.string();
  }

  /// summary.txt as key -> value.
  std::map<std::string, std::string> summary(const std::string& out) const {
    std::map<std::string, std::string> m;
    std::istringstream is(slurp(out + "/summary.txt"));
    std::string line;
    while (std::getline(is, line)) {
      const auto colon = line.find(": ");
      if (colon != std::string::npos) m[line.substr(0, colon)] = line.substr(colon + 2);
    }
    return m;
  }

  /// frames.csv's status column, and its message column.
  std::vector<std::string> column(const std::string& out, int index) const {
    std::vector<std::string> v;
    std::istringstream is(slurp(out + "/frames.csv"));
    std::string line;
    std::getline(is, line);  // header
    while (std::getline(is, line)) {
      std::vector<std::string> cells;
      std::istringstream ls(line);
      std::string cell;
      while (std::getline(ls, cell, ',')) cells.push_back(cell);
      v.push_back(index < static_cast<int>(cells.size()) ? cells[static_cast<size_t>(index)] : "");
    }
    return v;
  }
  std::vector<std::string> statuses(const std::string& out) const { return column(out, 2); }
  /// The message column (the last one: it may hold anything but commas).
  std::vector<std::string> messages(const std::string& out) const {
    std::istringstream is(slurp(out + "/frames.csv"));
    std::string header;
    std::getline(is, header);
    return column(out, static_cast<int>(std::count(header.begin(), header.end(), ',')));
  }

  fs::path dir_;
};

}  // namespace sgd_test
