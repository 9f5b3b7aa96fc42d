// A file the page saves for the person (the browser's download): a program, its Python, a ROS 2
// package's zip, a history span's CSV and PNG, a plot's. data: a Blob (its own type) or what a Blob
// is made of (text, bytes) with `type`.
export function download(filename, data, type = 'application/json') {
  const blob = data instanceof Blob ? data : new Blob([data], { type });
  const a = document.createElement('a');
  a.href = URL.createObjectURL(blob);
  a.download = filename;
  document.body.append(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(a.href), 10000);   // (a large file's save may start late)
}
