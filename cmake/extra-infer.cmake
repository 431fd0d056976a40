# roe infer: the app tests render synthetic frames with OpenCV (tests/app/test_infer.cpp).
if(TARGET test_app)
  target_include_directories(test_app PRIVATE ${OpenCV_INCLUDE_DIRS})
endif()
