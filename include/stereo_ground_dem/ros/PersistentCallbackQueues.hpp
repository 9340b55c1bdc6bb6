#pragma once
/// \file PersistentCallbackQueues.hpp
/// Callback queues for a nodelet that outlive it: a single-threaded and a multi-threaded queue (the
/// nodelet's usual pair), each spun by its own AsyncSpinner, and deliberately never freed.
///
/// Why (the "double free or corruption" at exit, docs/ros.md "Shutdown"): on Ctrl-C roslaunch sends
/// SIGINT to the nodelet manager and to the `nodelet load` client at once. The client asks the
/// manager to unload the nodelet while the manager's ros::shutdown() is already dropping every
/// service, subscription and publication: ServiceManager::shutdown() takes the list of publications,
/// blocks in drop() of `unload_nodelet` until that callback (the nodelet's destruction) returns, then
/// drops the nodelet's own services and subscriptions, whose callback_queue_ pointers name the
/// nodelet's queues - freed with the nodelet: a use-after-free (SIGSEGV in
/// ros::ServicePublication::drop(), or heap corruption reported as "double free or corruption").
/// Entities whose queues are never freed cannot dangle, whatever the order. Cost: two small queue
/// objects left allocated per unloaded nodelet.

#include <ros/callback_queue.h>
#include <ros/node_handle.h>
#include <ros/spinner.h>

#include <memory>

namespace stereo_ground_dem {

class PersistentCallbackQueues {
 public:
  explicit PersistentCallbackQueues(int mt_threads = 2);
  ~PersistentCallbackQueues();  ///< stop(); the queues stay allocated

  /// A copy of `from` (namespace, remappings) whose callbacks go to the single-threaded queue.
  ros::NodeHandle singleThreaded(const ros::NodeHandle& from) const;
  /// ... to the multi-threaded queue.
  ros::NodeHandle multiThreaded(const ros::NodeHandle& from) const;

  void start();
  /// Stops the spinners; returns when no callback of these queues runs any more.
  void stop();

 private:
  ros::CallbackQueue* st_queue_;  // never deleted (see the file comment)
  ros::CallbackQueue* mt_queue_;  // never deleted
  std::unique_ptr<ros::AsyncSpinner> st_spinner_, mt_spinner_;
};

}  // namespace stereo_ground_dem
