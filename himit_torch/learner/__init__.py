"""The learner: settings, state (one owner per piece), the equations, and the engines."""
