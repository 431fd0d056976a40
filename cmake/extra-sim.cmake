# roe simulate: the presets configs/sim/*.json compiled into roe_app (cmake/embed.cmake).
roe_embed_files(roe_app embedded_sim_presets ${CMAKE_SOURCE_DIR}/configs/sim/*.json)
