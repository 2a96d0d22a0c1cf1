{$kind, $index, $start, $u0, $length}
