/* $loop: $step $count times ($ops each) */
$signature {
  ${p}_real current[$size];
  ${p}_real next[$size];
  int k;
  int i;
  for (i = 0; i < $size; ++i) { current[i] = ${first}[i]; }
  for (k = 0; k < $count; ++k) {
$body
  }
  for (i = 0; i < $size; ++i) { final[i] = current[i]; }
}
