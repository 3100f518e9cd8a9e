// Planar geometry of ROS messages: quaternions about z, poses, and laser scans.

export function yawOfQuaternion(q = {}) {
  const { x = 0, y = 0, z = 0, w = 1 } = q;
  return Math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z));
}

export function quaternionOfYaw(yaw) {
  return { x: 0, y: 0, z: Math.sin(yaw / 2), w: Math.cos(yaw / 2) };
}

/** {x, y, yaw} of a geometry_msgs/Pose. */
export function planarPose(pose) {
  return { x: pose.position.x, y: pose.position.y, yaw: yawOfQuaternion(pose.orientation) };
}

/** A geometry_msgs/PoseStamped in `frameId` (a Map ID) at {x, y, yaw}. */
export function poseStamped(frameId, { x, y, yaw }) {
  return {
    header: { frame_id: frameId, stamp: nowStamp() },
    pose: { position: { x, y, z: 0 }, orientation: quaternionOfYaw(yaw) },
  };
}

/** A geometry_msgs/PoseWithCovarianceStamped, with the spread rviz gives an estimate. */
export function poseWithCovariance(frameId, pose) {
  const covariance = new Array(36).fill(0);
  covariance[0] = 0.25 ** 2;
  covariance[7] = 0.25 ** 2;
  covariance[35] = (Math.PI / 12) ** 2;
  const stamped = poseStamped(frameId, pose);
  return { header: stamped.header, pose: { pose: stamped.pose, covariance } };
}

export function nowStamp() {
  const ms = Date.now();
  return { sec: Math.floor(ms / 1000), nanosec: (ms % 1000) * 1e6 };
}

/** Laser points in the map frame, seen from a robot at `pose` (the laser at its centre). */
export function scanPoints(scan, pose, stride = 1) {
  const points = [];
  const cos = Math.cos(pose.yaw);
  const sin = Math.sin(pose.yaw);
  const ranges = scan.ranges || [];
  for (let i = 0; i < ranges.length; i += stride) {
    const range = ranges[i];
    if (range === null || !(range >= scan.range_min && range <= scan.range_max)) continue;
    const angle = scan.angle_min + i * scan.angle_increment;
    const lx = range * Math.cos(angle);
    const ly = range * Math.sin(angle);
    points.push({ x: pose.x + cos * lx - sin * ly, y: pose.y + sin * lx + cos * ly });
  }
  return points;
}

export function degrees(radians) {
  return (radians * 180) / Math.PI;
}
