// rawlog-to-sf: turns the observation-only rawlog that MRPT's `carmen2rawlog` writes (one
// CObservation2DRangeScan and one CObservationOdometry per FLASER line) into the
// action / sensory-frame rawlog that MRPT's `rbpf-slam` reads (MRPT 2.5's app dereferences
// the action of every entry, so an observation-only rawlog crashes it).
//
// For the k-th scan it writes a CActionCollection holding a CActionRobotMovement2D with the
// odometry increment since scan k-1 (odom_{k-1}^-1 (+) odom_k; zero for the first scan),
// MRPT's default Gaussian motion model, then a CSensoryFrame holding the scan, unchanged.
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
