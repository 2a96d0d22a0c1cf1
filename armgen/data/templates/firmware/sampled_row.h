    $values,
