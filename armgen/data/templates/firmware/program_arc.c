{$centre, $radius, $e1, $e2, $length, $quaternion, $rotvec, $omega}
