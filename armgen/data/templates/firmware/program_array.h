static const $ctype ${name}_$attr[$macro] = {
  $items
};
