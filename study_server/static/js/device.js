// Reports the browser window and input to the server's device check, then continues on its own.
const form = document.getElementById("device-form");
if (form) {
  form.width.value = String(window.innerWidth);
  form.height.value = String(window.innerHeight);
  form.pixel_ratio.value = String(window.devicePixelRatio || 1);
  const coarse = window.matchMedia && window.matchMedia("(pointer: coarse)").matches;
  const fine = window.matchMedia && window.matchMedia("(any-pointer: fine)").matches;
  form.touch_only.value = coarse && !fine ? "true" : "false";
  form.submit();
}
