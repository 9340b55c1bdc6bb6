#!/usr/bin/env python3
"""HeightGrid / HeightGridInfo are field-identical to grid_map_msgs/GridMap / GridMapInfo (ROS 1).

grid_map is not packaged for Debian, so its two definitions are written here (grid_map_msgs 1.6,
msg/GridMap.msg and msg/GridMapInfo.msg without comments). The test compares the generated Python
classes' field names and types with them, and the MD5 sums genmsg computes for both definitions:
equal MD5 sums mean a grid_map subscriber accepts our bytes (after a topic type remap)."""
import os
import sys
import unittest

import genmsg
import genmsg.msg_loader
import rostest
from stereo_ground_dem.msg import HeightGrid, HeightGridInfo

GRID_MAP_INFO = """std_msgs/Header header
float64 resolution
float64 length_x
float64 length_y
geometry_msgs/Pose pose
"""
GRID_MAP = """grid_map_msgs/GridMapInfo info
string[] layers
string[] basic_layers
std_msgs/Float32MultiArray[] data
uint16 outer_start_index
uint16 inner_start_index
"""


def search_path():
    path = {}
    for pkg in ('std_msgs', 'geometry_msgs'):
        for base in os.environ.get('ROS_PACKAGE_PATH', '').split(':') + ['/usr/share', '/opt/ros/noetic/share']:
            d = os.path.join(base, pkg, 'msg')
            if os.path.isdir(d):
                path[pkg] = [d]
                break
    return path


class MessageLayoutTest(unittest.TestCase):
    def setUp(self):
        self.ctx = genmsg.msg_loader.MsgContext.create_default()
        self.path = search_path()
        self.info = genmsg.msg_loader.load_msg_from_string(self.ctx, GRID_MAP_INFO, 'grid_map_msgs/GridMapInfo')
        self.ctx.register('grid_map_msgs/GridMapInfo', self.info)
        self.grid = genmsg.msg_loader.load_msg_from_string(self.ctx, GRID_MAP, 'grid_map_msgs/GridMap')
        self.ctx.register('grid_map_msgs/GridMap', self.grid)
        genmsg.msg_loader.load_depends(self.ctx, self.info, self.path)
        genmsg.msg_loader.load_depends(self.ctx, self.grid, self.path)

    def test_fields(self):
        self.assertEqual(list(HeightGridInfo.__slots__), list(self.info.names))
        self.assertEqual(list(HeightGridInfo._slot_types), list(self.info.types))
        self.assertEqual(list(HeightGrid.__slots__), list(self.grid.names))
        ours = [t.replace('stereo_ground_dem/HeightGridInfo', 'grid_map_msgs/GridMapInfo')
                for t in HeightGrid._slot_types]
        self.assertEqual(ours, list(self.grid.types))

    def test_md5(self):
        self.assertEqual(HeightGridInfo._md5sum, genmsg.compute_md5(self.ctx, self.info))
        self.assertEqual(HeightGrid._md5sum, genmsg.compute_md5(self.ctx, self.grid))
        # the published grid_map_msgs/GridMap MD5 sum (e.g. `rosbag info` of grid_map bags)
        self.assertEqual(HeightGrid._md5sum, '95681e052b1f73bf87b7eb984382b401')


if __name__ == '__main__':
    rostest.rosrun('stereo_ground_dem', 'message_layout', MessageLayoutTest, sys.argv)
