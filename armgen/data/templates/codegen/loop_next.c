    current[$i] = next[$i];
