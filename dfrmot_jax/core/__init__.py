"""The tracker itself: jittable, pure functions. Imports only itself and the package's config."""
