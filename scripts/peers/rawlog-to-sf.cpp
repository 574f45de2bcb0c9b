// rawlog-to-sf: turns the observation-only rawlog that MRPT's `carmen2rawlog` writes (one
// CObservation2DRangeScan and one CObservationOdometry per FLASER line) into the
// action / sensory-frame rawlog that MRPT's `rbpf-slam` reads (MRPT 2.5's app dereferences
// the action of every entry, so an observation-only rawlog crashes it).
//
// For the k-th scan it writes a CActionCollection holding a CActionRobotMovement2D with the
// odometry increment since scan k-1 (odom_{k-1}^-1 (+) odom_k; zero for the first scan),
// MRPT's default Gaussian motion model, then a CSensoryFrame holding the scan.
//
// The scan's beam geometry is set as slam-io reads a FLASER line (the line states none;
// the datasets README: a 180 deg field of view, beam k at -90 deg + k*res, res = 180 deg/N
// for N = 180 or 360, 180 deg/(N-1) otherwise). carmen2rawlog 2.5 gives a 180-beam scan
// an aperture of 90 deg, which squeezes every scan to half its width. MRPT spreads N beams
// evenly over `aperture` centred on the sensor's heading, so aperture = (N-1)*res and the
// sensor yaw is the centre of the span (-0.5 deg for N = 180). Ranges and validity flags
// (readings at or beyond maxRange are invalid) are kept.
// Our own adapter, compiled by `cargo xtask eval speed` against Debian's libmrpt-obs-dev;
// no MRPT source is built.
//
// Usage: rawlog-to-sf IN.rawlog OUT.rawlog
#include <mrpt/io/CFileGZOutputStream.h>
#include <mrpt/obs/CActionCollection.h>
#include <mrpt/obs/CActionRobotMovement2D.h>
#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/obs/CRawlog.h>
#include <mrpt/obs/CSensoryFrame.h>
#include <mrpt/serialization/CArchive.h>

#include <cmath>
#include <iostream>
#include <vector>

int main(int argc, char** argv)
{
  using namespace mrpt::obs;
  if (argc != 3)
  {
    std::cerr << "usage: rawlog-to-sf IN.rawlog OUT.rawlog\n";
    return 2;
  }
  try
  {
    CRawlog in;
    if (!in.loadFromRawLogFile(argv[1]))
    {
      std::cerr << argv[1] << ": cannot read as a rawlog\n";
      return 1;
    }
    std::vector<CObservation2DRangeScan::Ptr> scans;
    std::vector<mrpt::poses::CPose2D> odometry;
    for (size_t i = 0; i < in.size(); i++)
    {
      if (in.getType(i) != CRawlog::etObservation) continue;
      const auto obs = in.getAsObservation(i);
      if (auto s = std::dynamic_pointer_cast<CObservation2DRangeScan>(obs))
        scans.push_back(s);
      else if (auto o = std::dynamic_pointer_cast<CObservationOdometry>(obs))
        odometry.push_back(o->odometry);
    }
    if (scans.empty() || scans.size() != odometry.size())
    {
      std::cerr << argv[1] << ": " << scans.size() << " scans and " << odometry.size()
                << " odometry readings; expected one of each per FLASER line\n";
      return 1;
    }
    mrpt::io::CFileGZOutputStream out(argv[2]);
    auto arch = mrpt::serialization::archiveFrom(out);
    const CActionRobotMovement2D::TMotionModelOptions model;
    for (size_t k = 0; k < scans.size(); k++)
    {
      const auto increment =
          k == 0 ? mrpt::poses::CPose2D() : odometry[k] - odometry[k - 1];
      CActionRobotMovement2D move;
      move.computeFromOdometry(increment, model);
      move.timestamp = scans[k]->timestamp;
      CActionCollection actions;
      actions.insert(move);
      auto& scan = *scans[k];
      const size_t n = scan.getScanSize();
      if (n < 2)
      {
        std::cerr << argv[1] << ": scan " << k << " has " << n << " beams\n";
        return 1;
      }
      const double res = (n == 180 || n == 360) ? M_PI / n : M_PI / (n - 1);
      scan.aperture = static_cast<float>((n - 1) * res);
      scan.rightToLeft = true;
      auto pose = scan.sensorPose;
      pose.setYawPitchRoll(-M_PI / 2 + 0.5 * (n - 1) * res, 0, 0);
      scan.setSensorPose(pose);
      CSensoryFrame frame;
      frame.insert(scans[k]);
      arch << actions << frame;
    }
    std::cout << "rawlog-to-sf: " << scans.size() << " scans written to " << argv[2] << "\n";
    return 0;
  }
  catch (const std::exception& e)
  {
    std::cerr << mrpt::exception_to_str(e) << "\n";
    return 1;
  }
}
