#include "ppf_trajectory/trajectory_io.hpp"

#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>

#include <Eigen/SVD>

namespace ppf {
namespace {

bool ReadFile(const std::string& path, std::string* text, std::string* error) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    if (error) *error = "cannot open " + path;
    return false;
  }
  std::ostringstream os;
  os << in.rdbuf();
  *text = os.str();
  return true;
}

// Splits into numbers; false if a token is not a number.
bool ParseNumbers(const std::string& line, std::vector<double>* v) {
  v->clear();
  std::istringstream is(line);
  std::string tok;
  while (is >> tok) {
    char* end = nullptr;
    const double x = std::strtod(tok.c_str(), &end);
    if (end == tok.c_str() || *end != '\0' || !std::isfinite(x)) return false;
    v->push_back(x);
  }
  return true;
}

}  // namespace

bool ParseTum(const std::string& text, Trajectory* traj, std::string* error) {
  traj->clear();
  std::istringstream is(text);
  std::string line;
  std::vector<double> v;
  for (int n = 1; std::getline(is, line); ++n) {
    const size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    if (!ParseNumbers(line, &v) || v.size() != 8) {
      if (error) *error = "TUM line " + std::to_string(n) + ": expected 8 numbers";
      return false;
    }
    Eigen::Quaterniond q(v[7], v[4], v[5], v[6]);
    if (q.norm() < 1e-9) {
      if (error) *error = "TUM line " + std::to_string(n) + ": zero quaternion";
      return false;
    }
    StampedPose p;
    p.stamp_s = v[0];
    p.T.linear() = q.normalized().toRotationMatrix();
    p.T.translation() = Eigen::Vector3d(v[1], v[2], v[3]);
    traj->push_back(p);
  }
  return true;
}

bool ReadTum(const std::string& path, Trajectory* traj, std::string* error) {
  std::string text;
  return ReadFile(path, &text, error) && ParseTum(text, traj, error);
}

namespace {

// "%.9f" of the seven pose numbers after the stamp text; see the header for the choice.
std::string FormatPose(const std::string& stamp, const Eigen::Isometry3d& T) {
  Eigen::Quaterniond q(T.linear());
  q.normalize();
  if (q.w() < 0) q.coeffs() *= -1.0;
  const Eigen::Vector3d t = T.translation();
  char buf[256];
  std::snprintf(buf, sizeof(buf), "%s %.9f %.9f %.9f %.9f %.9f %.9f %.9f", stamp.c_str(), t.x(),
                t.y(), t.z(), q.x(), q.y(), q.z(), q.w());
  return buf;
}

}  // namespace

std::string FormatTumLine(const StampedPose& pose) {
  char stamp[64];
  std::snprintf(stamp, sizeof(stamp), "%.9f", pose.stamp_s);
  return FormatPose(stamp, pose.T);
}

std::string FormatTumLine(int64_t stamp_ns, const Eigen::Isometry3d& T_world_body) {
  // Sign and magnitude separately: the "%09" fraction of a negative stamp would carry a '-'.
  const uint64_t abs_ns =
      stamp_ns < 0 ? 0 - static_cast<uint64_t>(stamp_ns) : static_cast<uint64_t>(stamp_ns);
  const uint64_t ns_per_s = 1000000000;
  char stamp[64];
  std::snprintf(stamp, sizeof(stamp), "%s%" PRIu64 ".%09" PRIu64, stamp_ns < 0 ? "-" : "",
                abs_ns / ns_per_s, abs_ns % ns_per_s);
  return FormatPose(stamp, T_world_body);
}

TumWriter::TumWriter(const std::string& path, const std::string& comment) : out_(path) {
  if (out_ && !comment.empty()) out_ << "# " << comment << '\n';
}

void TumWriter::Write(const StampedPose& pose) { out_ << FormatTumLine(pose) << '\n'; }

void TumWriter::Write(int64_t stamp_ns, const Eigen::Isometry3d& T_world_body) {
  out_ << FormatTumLine(stamp_ns, T_world_body) << '\n';
}

bool TumWriter::Close() {
  if (!out_.is_open()) return false;
  out_.flush();
  const bool ok = static_cast<bool>(out_);
  out_.close();
  return ok && static_cast<bool>(out_);
}

bool WriteTum(const std::string& path, const Trajectory& traj) {
  TumWriter writer(path, "timestamp tx ty tz qx qy qz qw");
  for (const StampedPose& p : traj) writer.Write(p);
  return writer.Close();
}

bool ParseKitti(const std::string& text, Trajectory* traj, std::string* error) {
  traj->clear();
  std::istringstream is(text);
  std::string line;
  std::vector<double> v;
  for (int n = 1; std::getline(is, line); ++n) {
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    if (!ParseNumbers(line, &v) || v.size() != 12) {
      if (error) *error = "KITTI line " + std::to_string(n) + ": expected 12 numbers";
      return false;
    }
    StampedPose p;
    p.stamp_s = static_cast<double>(traj->size());
    Eigen::Matrix3d R;
    R << v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10];
    // Files carry rounded rotations: project onto SO(3).
    const Eigen::JacobiSVD<Eigen::Matrix3d> svd(R, Eigen::ComputeFullU | Eigen::ComputeFullV);
    R = svd.matrixU() * svd.matrixV().transpose();
    p.T.linear() = R;
    p.T.translation() = Eigen::Vector3d(v[3], v[7], v[11]);
    traj->push_back(p);
  }
  return true;
}

bool ReadKitti(const std::string& path, Trajectory* traj, std::string* error) {
  std::string text;
  return ReadFile(path, &text, error) && ParseKitti(text, traj, error);
}

bool WriteKitti(const std::string& path, const Trajectory& traj) {
  std::ofstream out(path);
  if (!out) return false;
  char buf[64];
  for (const StampedPose& p : traj) {
    const Eigen::Matrix4d m = p.T.matrix();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 4; ++c) {
        std::snprintf(buf, sizeof(buf), "%.9e", m(r, c));
        out << buf << ((r == 2 && c == 3) ? '\n' : ' ');
      }
    }
  }
  return static_cast<bool>(out);
}

}  // namespace ppf
