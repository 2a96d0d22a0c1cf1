$preamble

$body
