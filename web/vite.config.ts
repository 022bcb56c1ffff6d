// The console bundle: web/dist, embedded in laparo-server (server/src/console).
import { defineConfig } from "vite";

export default defineConfig({
  base: "/",
  build: {
    outDir: "dist",
    emptyOutDir: true,
    // three.js is most of the bundle; one file is fine for a page served locally.
    chunkSizeWarningLimit: 2000,
    sourcemap: false,
  },
});
