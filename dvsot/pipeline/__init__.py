"""From inputs to dataset files: a scene rendered (generate), frames you have (simulate), the frames -> events ->
file loop both share (sequence), and scenes as checked tasks (scene_sources, scene_task) rendered by one path,
here or on a cluster, with a manifest (many_scenes, manifest)."""
