{$x, $quaternion, $position, $rotvec}
