// What cameras this machine has: V4L2 video devices and libcamera cameras (for `rangebayes cameras`).
#pragma once

#include <string>
#include <vector>

#include "capture/v4l2_syscalls.h"

namespace rangebayes {

struct V4l2DeviceInfo {
  std::string path;                  // /dev/videoN
  std::string card;                  // device name
  std::string driver;
  std::string bus;
  bool can_capture = false;          // video capture with streaming i/o (metadata nodes say false)
  std::vector<std::string> formats;  // fourcc names offered
  std::string error;                 // why the device could not be queried (busy, permissions)
};

// Every /dev/video* under `dev_dir`, sorted by number. Never throws for a single device; an unreadable
// dev_dir gives an empty list.
std::vector<V4l2DeviceInfo> ListV4l2Devices(V4l2SysCalls& sys, const std::string& dev_dir = "/dev");

struct LibcameraCameraInfo {
  std::string id;
  std::string model;  // from the camera properties when known
};

struct LibcameraList {
  bool manager_started = false;
  std::string error;  // why the camera manager could not start
  std::vector<LibcameraCameraInfo> cameras;
};

// Starts a libcamera CameraManager and lists its cameras (zero on a machine without camera hardware).
LibcameraList ListLibcameraCameras();

}  // namespace rangebayes
