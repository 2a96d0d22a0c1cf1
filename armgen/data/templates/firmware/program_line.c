{$p0, $direction, $length, $quaternion, $rotvec, $omega}
