"""Scenes: the model, loaders (glTF, OBJ, TOML) and built-in meshes."""
