// The device check in a browser that cannot load JavaScript modules (device.js never runs there): report that,
// and continue to the page that says so. Old syntax on purpose.
(function () {
  var form = document.getElementById("device-form");
  if (!form) return;
  form.missing.value = "modules";
  form.width.value = String(window.innerWidth || 0);
  form.height.value = String(window.innerHeight || 0);
  form.pixel_ratio.value = String(window.devicePixelRatio || 1);
  form.submit();
})();
