void ${p}_batch_$function(long n, $parameters);
void ${p}_batch_$function(long n, $parameters) {
  long s;
  for (s = 0; s < n; ++s) (void)${p}_$function($arguments);
}
