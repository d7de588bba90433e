// Loader of the browser viewer: checks that three.js is installed (scripts/setup.sh puts it
// in /static/vendor/three/; nothing is ever fetched from another machine), then starts
// the viewer application (viewer-app.js).
const status = document.getElementById("status");
// a placeholder until the application replaces it (tests poll it)
window.realizerViewer = { ready: false, meshLoaded: false, frames: 0, feedback: [], errors: [] };
try {
  await import("/static/viewer-app.js");
} catch (error) {
  const hint = /fetch|import|resolve/i.test(String(error.message))
    ? " (is three.js installed? run scripts/setup.sh)" : "";
  status.textContent = `the viewer could not start: ${error.message}${hint}`;
  status.className = "bad";
  window.realizerViewer.failed = String(error.message);
}
