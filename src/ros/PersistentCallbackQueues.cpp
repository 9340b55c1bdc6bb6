#include "stereo_ground_dem/ros/PersistentCallbackQueues.hpp"

namespace stereo_ground_dem {

PersistentCallbackQueues::PersistentCallbackQueues(int mt_threads)
    : st_queue_(new ros::CallbackQueue()),
      mt_queue_(new ros::CallbackQueue()),
      st_spinner_(std::make_unique<ros::AsyncSpinner>(1, st_queue_)),
      mt_spinner_(std::make_unique<ros::AsyncSpinner>(static_cast<uint32_t>(mt_threads < 1 ? 1 : mt_threads),
                                                      mt_queue_)) {}

PersistentCallbackQueues::~PersistentCallbackQueues() {
  stop();
  // Not deleted: ros::shutdown() may still drop entities that point at them (see the header).
  // Disabled, so that nothing is queued into them from now on.
  st_queue_->disable();
  mt_queue_->disable();
}

ros::NodeHandle PersistentCallbackQueues::singleThreaded(const ros::NodeHandle& from) const {
  ros::NodeHandle nh(from);
  nh.setCallbackQueue(st_queue_);
  return nh;
}

ros::NodeHandle PersistentCallbackQueues::multiThreaded(const ros::NodeHandle& from) const {
  ros::NodeHandle nh(from);
  nh.setCallbackQueue(mt_queue_);
  return nh;
}

void PersistentCallbackQueues::start() {
  st_spinner_->start();
  mt_spinner_->start();
}

void PersistentCallbackQueues::stop() {
  st_spinner_->stop();
  mt_spinner_->stop();
}

}  // namespace stereo_ground_dem
